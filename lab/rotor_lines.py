"""How far any honest rotor count can go on our simulator's long-dwell conditions (docs/features.md,
"Long dwells").

The check counts the rotors whose flashes stand above the noise (`signatures.dsp.rotor_lines`) at a 1 %
false-alarm rate. This oracle knows more than any count can: each rotor of a `lab.accuracy`
condition scene is rendered *alone* (the body, its own blades, the scene's clutter and noise draws),
and its flash envelope is folded at its *true* pattern rate over the whole dwell; it is visible
where a phase bin's sum stands above the noise at the same false-alarm rate (Bonferroni over the
phase bins only). No count that must find the rates, tell the rotors apart and see past the other
rotors' flashes sees more.

`--search` holds the oracle to the count's own threshold instead: Bonferroni over the phase bins
*and* the rate offsets the count searches (`signatures.dsp.rotor_lines.searched_slopes`), the price of
not knowing the rates. That bounds any count that searches those rates at that false-alarm rate.

    python -m lab.rotor_lines --condition cw-hover-tagged --condition cw-idle-tagged --n 120
    python -m lab.rotor_lines --condition cw-hover-tagged --condition cw-idle-tagged --n 120 --search
"""

from __future__ import annotations

import argparse
import contextlib
import math
from collections.abc import Iterator
from statistics import NormalDist
from typing import Any

import numpy as np

from lab.accuracy import CONDITIONS
from signatures.dsp.rotor_lines import FALSE_LINES, phase_time, searched_slopes


@contextlib.contextmanager
def _one_rotor(keep: int) -> Iterator[dict[str, float]]:
    """While open, `signatures.sim.simulate` renders the body and rotor `keep` only (the other rotors'
    columns zeroed, every random draw as before); the dict receives `scale`, the amplitude that puts
    the lone rotor back at its level in the whole scene (the simulator normalises the target's power)."""
    import signatures.sim.simulate as sim

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


def rotors_alone(condition: Any, seed: int, false_alarm: float = FALSE_LINES,
                 search: bool = False) -> list[tuple[bool, bool, float]]:
    """The oracle bound on an honest rotor count, for one seeded scene of a `lab.accuracy` condition
    in our simulator: per rotor, (visible, tagged, z). Each rotor is rendered alone (the body, its
    own blades, the scene's clutter and noise draws) and its flash envelope folded at its *true*
    pattern rate over the whole dwell; it is visible where a phase bin's sum stands `false_alarm`
    (per rotor, Bonferroni over the bins) above the noise. No estimator that knows less (the rates,
    which rotor is which, the others' flashes in between) sees more at that false-alarm rate.
    `search`: Bonferroni over the count's searched rate offsets too (module docstring)."""
    import signatures.sim.simulate as sim
    from signatures.dsp.flash_spectrum import flash_envelope

    scene, pre, sim_seed = condition.draw(seed)
    out = []
    for i in range(scene.profile.rotors):
        with _one_rotor(i) as lone:
            c = sim.render(scene, pre.config, pre.n_chirps, pre.n_samples, sim_seed)
        truth, rate = c.truth, c.truth.pattern_rates_hz[i]  # the whole scene's truth, every render alike
        iq = c.target * np.float32(lone["scale"]) + c.noise + (0 if c.clutter is None else c.clutter)
        env, _ = flash_envelope(iq[None, :, :1], pre.config, np.zeros(1))
        image, var = phase_time(env[0], rate * pre.config.pri_s)
        z = float((image.sum(axis=0) / np.sqrt(np.maximum(var.sum(axis=0), 1e-300))).max())
        tagged = bool(truth.blade_weights) and max(truth.blade_weights[i]) > 1.0
        tests = image.shape[1] * (searched_slopes(*image.shape).size if search else 1)
        out.append((z >= NormalDist().inv_cdf(1.0 - false_alarm / tests), tagged, z))
    return out


def oracle_table(conditions: list[str], n: int, search: bool = False) -> list[str]:
    """Per condition (our simulator): how often the oracle's count (`rotors_alone`) is within +-1 of
    the rotors, and how many untagged rotors it sees."""
    lines = ["| condition | n | oracle count within +-1 | untagged rotors visible alone |", "|---|---|---|---|"]
    for name in conditions:
        ok = seen = untagged = 0
        for i in range(n):
            rotors = rotors_alone(CONDITIONS[name], i, search=search)
            ok += abs(sum(v for v, _, _ in rotors) - len(rotors)) <= 1
            seen += sum(v and not t for v, t, _ in rotors)
            untagged += sum(not t for _, t, _ in rotors)
        lines.append(f"| {name} | {n} | {ok / n:.1%} | {seen} of {untagged} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lab.rotor_lines", description=__doc__.split("\n\n")[0])
    ap.add_argument("--condition", action="append", choices=sorted(CONDITIONS), required=True)
    ap.add_argument("--n", type=int, default=40, help="scenes per condition (lab.accuracy's seeds 0..n-1)")
    ap.add_argument("--search", action="store_true", help="the count's threshold: Bonferroni over its rates too")
    a = ap.parse_args(argv)
    if a.n < 1:
        ap.error(f"--n {a.n}: at least 1")
    print("\n".join(oracle_table(a.condition, a.n, a.search)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
