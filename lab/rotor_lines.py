"""A candidate long-dwell rotor count that counts only what stands above the noise (docs/features.md).

Today's long-dwell count (`signatures.flash._rotors_seen`) folds the flash envelope in windows of a
few flash periods and counts the folded profile's peaks; pure noise reads 4-5 rotors at a 330 Hz
flash rate and 9-11 at 130 Hz. This candidate asks, for each rotor, whether its flashes stand above
the noise over the whole dwell:

* windows of `PERIODS` flash periods are folded at the estimated flash rate into one row each of
  a phase-time image (window x phase bin), each bin a mean with its own standard error (from the
  spread of the samples it averages);
* a rotor is a straight line in that image: its phase drifts by its rate's offset from the folded
  rate (searched over +-`MAX_DRIFT`). Every line's sum over the windows comes at once from
  zero-padded FFTs over the windows (one per phase harmonic), in units of the sum's standard error;
* lines are taken strongest first while one exceeds a Bonferroni threshold over the slopes and
  phases searched (`FALSE_LINES`: the chance that noise alone makes a line in a dwell); each is
  subtracted (its mean flash shape and skirts, fitted per window; the rows re-centred, since each
  row's mean held the line's power) before the next is sought, and a line that drifts less than a
  period from one already counted and stays within its skirts for half the dwell is that line's
  residue or that line bent.

Not wired into the check: in 0.82 s it counts mostly the *tagged* rotors (untagged ones sit near
the noise), which today's symmetric rotor band would hold against a genuine few-tag quad.
`python -m lab.rotor_lines --condition cw-hover-tagged --world training` scores it beside today's
count on `lab.accuracy`'s condition scenes; `--oracle` measures the bound no count reaches past at
the same false-alarm rate (`rotors_alone`: each rotor rendered alone and folded at its true rate).
"""

from __future__ import annotations

import argparse
import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass
from statistics import NormalDist
from typing import Any

import numpy as np

from lab.accuracy import CONDITIONS, Estimate
from signatures.recording import Recording

#: Flash periods folded into one window (row) of the phase-time image.
PERIODS = 4
#: Largest relative rate offset of a rotor from the folded rate that is searched.
MAX_DRIFT = 0.03
#: Chance that noise alone makes one line in a dwell (the Bonferroni threshold's level).
FALSE_LINES = 0.01
#: Most lines taken from one dwell.
MAX_LINES = 16
#: Zero-padding factor of the FFTs over windows (the slope sums' interpolation).
PAD = 8


@dataclass(frozen=True)
class Line:
    """One rotor's flashes: phase drift per window (bins), phase at window 0 (bin), and z (sum over
    windows in units of its standard error)."""

    slope: float
    phase: int
    z: float


def phase_time(envelope: np.ndarray, cycles_per_pulse: float, periods: int = PERIODS
               ) -> tuple[np.ndarray, np.ndarray]:
    """(image, variance): the envelope folded at `cycles_per_pulse` in windows of `periods` flash
    periods, each row less its mean (window, phase bin), and each bin mean's variance."""
    period = 1.0 / cycles_per_pulse
    bins = max(8, int(round(period)))
    win = max(1, int(round(periods * period)))
    rows = envelope.size // win
    t = np.arange(rows * win)
    phase = np.minimum(((t * cycles_per_pulse) % 1.0 * bins).astype(int), bins - 1)
    idx = (t // win) * bins + phase
    x = np.asarray(envelope[: rows * win], dtype=np.float64)
    count = np.maximum(np.bincount(idx, minlength=rows * bins), 1).reshape(rows, bins)
    mean = np.bincount(idx, weights=x, minlength=rows * bins).reshape(rows, bins) / count
    second = np.bincount(idx, weights=x * x, minlength=rows * bins).reshape(rows, bins) / count
    var = np.maximum(second - mean * mean, 0.0) / np.maximum(count - 1, 1)
    return mean - mean.mean(axis=1, keepdims=True), var


def visible_rotors(envelope: np.ndarray, cycles_per_pulse: float, periods: int = PERIODS,
                   max_drift: float = MAX_DRIFT, false_lines: float = FALSE_LINES) -> list[Line]:
    """The rotors whose flashes stand above the noise in a long dwell's flash envelope (module
    docstring), strongest first; [] for a rate of 0 or a dwell of fewer than 8 windows."""
    if not cycles_per_pulse > 0.0:
        return []
    image, var = phase_time(envelope, cycles_per_pulse, periods)
    rows, bins = image.shape
    if rows < 8:
        return []
    step = 0.5 / rows  # half a bin over the dwell
    reach = max_drift * periods * bins
    slopes = np.arange(-reach, reach + step / 2, step)
    z0 = NormalDist().inv_cdf(1.0 - false_lines / (slopes.size * bins))
    length = PAD * (1 << int(math.ceil(math.log2(rows))))
    m = np.fft.fftfreq(bins) * bins
    at = (m[None, :] * slopes[:, None] / bins) % 1.0 * length  # where each (slope, harmonic) reads
    k0 = np.floor(at).astype(int) % length
    k1 = (k0 + 1) % length
    frac = at - np.floor(at)
    cols = np.arange(bins)[None, :]
    noise = math.sqrt(float(np.mean(var)) * rows)
    if noise <= 0.0:
        return []
    j = np.arange(rows)
    work = image.copy()
    found: list[Line] = []
    half = None
    for _ in range(MAX_LINES):
        spread = np.fft.ifft(np.fft.fft(work, axis=1), n=length, axis=0) * length  # sum_j F_j[m] e^{2 pi i k j / L}
        sums = np.fft.ifft(spread[k0, cols] * (1 - frac) + spread[k1, cols] * frac, axis=1).real / noise
        si, p0 = np.unravel_index(int(np.argmax(sums)), sums.shape)
        if sums[si, p0] < z0:
            break
        s0 = float(slopes[si])
        centre = np.rint(p0 + s0 * j).astype(int)  # the line's bin in each window
        aligned = work[j[:, None], (centre[:, None] + np.arange(bins)[None, :]) % bins].mean(axis=0)
        if half is None:  # the flash's half width from the strongest line, at most an eighth of a period
            half = 1
            while half < bins // 8 and min(aligned[half], aligned[-half]) > 0.5 * aligned[0]:
                half += 1
        width = min(2 * half, bins // 4)  # the flash and its skirts: what is left of a line is no new line
        offs = np.arange(-width, width + 1)
        at_line = (centre[:, None] + offs[None, :]) % bins
        shape = aligned[offs]
        amp = np.maximum(work[j[:, None], at_line] @ shape / max(float(shape @ shape), 1e-300), 0.0)
        work[j[:, None], at_line] -= amp[:, None] * shape[None, :]
        work -= work.mean(axis=1, keepdims=True)  # each row's mean held the line's power: re-centre
        bent = any(abs(s0 - f.slope) * rows < bins  # drifts apart by less than a period over the dwell
                   and np.mean(np.abs((p0 - f.phase + (s0 - f.slope) * j + bins / 2) % bins - bins / 2) <= width)
                   >= 0.5 for f in found)
        if not bent:
            found.append(Line(s0, int(p0), float(sums[si, p0])))
    return found


def _estimates(rec: Recording) -> tuple[Estimate, Estimate]:
    """(today's estimators, the same with the rotors seen replaced by `visible_rotors` on the
    dwell's flash envelope where the recording is a detected single-channel CW dwell: the channel
    is the gate), from one extraction."""
    from signatures.features import extract
    from signatures.flash import flash_envelope

    result = extract(rec)
    f = result.features
    today = Estimate(bool(f.detected > 0), float(f.rotor_rate_hz), float(f.radial_velocity_mps),
                     float(result.physics.get("rotors_seen", 0.0)))
    if rec.domain != "cw" or not today.detected:
        return today, today
    iq = np.asarray(rec.iq)
    body_hz = np.array([2.0 * today.radial_velocity_mps / rec.config.wavelength_m])
    total, _ = flash_envelope(iq.reshape(1, iq.shape[0], -1), rec.config, body_hz)
    seen = float(len(visible_rotors(total[0], float(f.flash_rate_hz) * rec.config.pri_s)))
    return today, Estimate(today.detected, today.rotor_rate_hz, today.radial_velocity_mps, seen)


@contextlib.contextmanager
def _one_rotor(keep: int) -> Iterator[dict[str, float]]:
    """While open, `signatures.simulate` renders the body and rotor `keep` only (the other rotors'
    columns zeroed, every random draw as before); the dict receives `scale`, the amplitude that puts
    the lone rotor back at its level in the whole scene (the simulator normalises the target's power)."""
    import signatures.simulate as sim

    original = sim._uav_amplitudes
    out: dict[str, float] = {}

    def lone(scene: Any, t: np.ndarray, wavelength: float, rng: np.random.Generator) -> tuple:
        amps, offsets, truth = original(scene, t, wavelength, rng)
        mask = np.zeros(amps.shape[1])
        mask[[0, 1 + keep]] = 1.0  # column 0 the fuselage, 1 + i rotor i's hub and blades
        kept = amps * mask[None, :]
        out["scale"] = math.sqrt(float(np.mean(np.abs(kept.sum(axis=1)) ** 2) / np.mean(np.abs(amps.sum(axis=1)) ** 2)))
        return kept, offsets, truth

    sim._uav_amplitudes = lone
    try:
        yield out
    finally:
        sim._uav_amplitudes = original


def rotors_alone(condition: Any, seed: int, false_alarm: float = FALSE_LINES) -> list[tuple[bool, bool, float]]:
    """The oracle bound on an honest rotor count, for one seeded scene of a `lab.accuracy` condition
    in our simulator: per rotor, (visible, tagged, z). Each rotor is rendered alone (the body, its
    own blades, the scene's clutter and noise draws) and its flash envelope folded at its *true*
    pattern rate over the whole dwell; it is visible where a phase bin's sum stands `false_alarm`
    (per rotor, Bonferroni over the bins) above the noise. No estimator that knows less (the rates,
    which rotor is which, the others' flashes in between) sees more at that false-alarm rate."""
    import signatures.simulate as sim
    from signatures.flash import flash_envelope

    rng = np.random.default_rng([seed, 31])  # lab.accuracy.render_condition's draws
    scene, pre = condition.scene(rng)
    sim_seed = int(rng.integers(2**31))
    truth = sim.render(scene, pre.config, pre.n_chirps, pre.n_samples, sim_seed).truth
    out = []
    for i, rate in enumerate(truth.pattern_rates_hz):
        with _one_rotor(i) as lone:
            c = sim.render(scene, pre.config, pre.n_chirps, pre.n_samples, sim_seed)
        iq = c.target * np.float32(lone["scale"]) + c.noise + (0 if c.clutter is None else c.clutter)
        env, _ = flash_envelope(iq[None, :, :1], pre.config, np.zeros(1))
        image, var = phase_time(env[0], rate * pre.config.pri_s)
        z = float((image.sum(axis=0) / np.sqrt(np.maximum(var.sum(axis=0), 1e-300))).max())
        tagged = bool(truth.blade_weights) and max(truth.blade_weights[i]) > 1.0
        out.append((z >= NormalDist().inv_cdf(1.0 - false_alarm / image.shape[1]), tagged, z))
    return out


def oracle_table(conditions: list[str], n: int) -> list[str]:
    """Per condition (our simulator): how often the oracle's count (`rotors_alone`) is within +-1 of
    the rotors, and how many untagged rotors it sees."""
    lines = ["| condition | n | oracle count within +-1 | untagged rotors visible alone |", "|---|---|---|---|"]
    for name in conditions:
        ok = seen = untagged = 0
        for i in range(n):
            rotors = rotors_alone(CONDITIONS[name], i)
            ok += abs(sum(v for v, _, _ in rotors) - len(rotors)) <= 1
            seen += sum(v and not t for v, t, _ in rotors)
            untagged += sum(not t for _, t, _ in rotors)
        lines.append(f"| {name} | {n} | {ok / n:.1%} | {seen} of {untagged} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    from lab.accuracy import render_condition

    ap = argparse.ArgumentParser(prog="python -m lab.rotor_lines", description=__doc__.split("\n\n")[0])
    ap.add_argument("--condition", action="append", choices=sorted(CONDITIONS), required=True)
    ap.add_argument("--world", action="append", choices=("training", "heldout"))
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--oracle", action="store_true",
                    help="the oracle bound instead (our simulator: each rotor alone, its true rate; rotors_alone)")
    a = ap.parse_args(argv)
    if a.n < 1:
        ap.error(f"--n {a.n}: at least 1")
    if a.oracle:
        print("\n".join(oracle_table(a.condition, a.n)))
        return 0
    if not a.world:
        ap.error("--world is needed (or --oracle)")
    print("| condition | world | n | rotors seen +-1: today's count / visible rotors | median count by tagged blades "
          "0 / 1 / 2 / 3 / 4+: today's; visible |")
    print("|---|---|---|---|---|")
    for cond in a.condition:
        for world in a.world:
            ok_today = ok_lines = 0
            by: dict[int, list[tuple[float, float]]] = {}
            for i in range(a.n):  # the seeds of evaluate_condition(seed=0)
                rec, scene, _, _, rotors = render_condition(CONDITIONS[cond], world, i)
                today, lines = _estimates(rec)
                ok_today += abs(today.rotors_seen - rotors) <= 1
                ok_lines += abs(lines.rotors_seen - rotors) <= 1
                by.setdefault(min(scene.tagged_blades, 4), []).append((today.rotors_seen, lines.rotors_seen))
            med = "; ".join(" / ".join(f"{np.median([v[k] for v in by[t]]):g}" if t in by else "-"
                                       for t in (0, 1, 2, 3, 4)) for k in (0, 1))
            print(f"| {cond} | {world} | {a.n} | {ok_today / a.n:.0%} / {ok_lines / a.n:.0%} | {med} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
