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
  subtracted (its mean flash shape, fitted per window) before the next is sought, and a line that
  stays within a flash width of one already counted for half the dwell is that line bent.

Not wired into the check: on our S-band world it counts the *tagged* rotors (untagged ones sit
near the noise), which today's symmetric rotor band would hold against a genuine few-tag quad.
`python -m lab.rotor_lines --condition cw-hover-tagged --world training` scores it beside today's
count on `lab.accuracy`'s condition scenes.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from statistics import NormalDist

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
        offs = np.arange(-half, half + 1)
        at_line = (centre[:, None] + offs[None, :]) % bins
        shape = aligned[offs]
        amp = np.maximum(work[j[:, None], at_line] @ shape / max(float(shape @ shape), 1e-300), 0.0)
        work[j[:, None], at_line] -= amp[:, None] * shape[None, :]
        bent = any(np.mean(np.abs(((p0 - f.phase) + (s0 - f.slope) * j + bins / 2) % bins - bins / 2) <= half) >= 0.5
                   for f in found)
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


def main(argv: list[str] | None = None) -> int:
    from lab.accuracy import render_condition

    ap = argparse.ArgumentParser(prog="python -m lab.rotor_lines", description=__doc__.split("\n\n")[0])
    ap.add_argument("--condition", action="append", choices=sorted(CONDITIONS), required=True)
    ap.add_argument("--world", action="append", choices=("training", "heldout"), required=True)
    ap.add_argument("--n", type=int, default=40)
    a = ap.parse_args(argv)
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
