"""One domain-randomisation knob at a time: what it does to the shipped bundle and the flash estimator.

    python benchmarks/randomisation_ablation.py --preset paper --n 60

For each knob of `signatures.sim.sampling.NuisanceDistribution` (all others held at the plain
simulator's values) it simulates `n` returns of the three shipped airframes at 10 dB and counts
(a) returns the shipped bundle labels as their own type, confidently (>= 0.6) and known, and
(b) flash-rate estimates within 5 % of the simulated rate. The figures in docs/signal-model.md
("Domain randomisation") come from this script.
"""

from __future__ import annotations

import argparse
from dataclasses import fields, replace

import numpy as np

from signatures.features import extract
from signatures.classify.inference import load_classifier
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.sampling import NuisanceDistribution, SceneDistribution, sample_scene
from signatures.sim.simulate import simulate

#: The plain simulator as a NuisanceDistribution (every span a point).
PLAIN = NuisanceDistribution(
    rotor_rate_scale=(1, 1), rotor_rate_jitter=(0.005, 0.005), attitude_wobble_deg=(1, 1),
    blade_to_body_db=(-13, -7), blade_rcs_spread=(0, 0), tip_weight=(0, 0), body_scatterers=(0, 0),
    radial_accel_mps2=(0, 0), phase_noise_rad=(0, 0), iq_gain_imbalance=(0, 0), iq_phase_imbalance_deg=(0, 0),
    dc_offset=(0, 0), adc_bits=(None,), beam_taper_db=(0, 0), clutter_spread_mps=(0, 0), blade_cone_deg=(0, 0))


def run(preset: str, n: int, knobs: list[str], tip_weight: tuple[float, float] | None) -> None:
    pre, clf = get_preset(preset), load_classifier(preset)
    profiles = list(shipped_profiles().values())
    full = NuisanceDistribution() if tip_weight is None else NuisanceDistribution(tip_weight=tip_weight)
    print(f"{preset}, {n} returns per knob at 10 dB")
    print(f"{'knob':24s} {'bundle: own type':>18s} {'flash rate +-5%':>16s}")
    for knob in knobs:
        nd = PLAIN if knob == "none" else replace(PLAIN, **{knob: getattr(full, knob)})
        dist = SceneDistribution(order=("range", "elevation", "speed", "snr", "clutter"), range_m=(100, 900),
                                 elevation_deg=(0, 40), hover_fraction=0.5, speed_mps=(1, 15), snr_db=(10, 10.01),
                                 clutter_band=(0, 0.3), clutter_db=(0, 10), nuisance=nd)
        rng = np.random.default_rng(5)
        own = rate = 0
        for i in range(n):
            p = profiles[i % len(profiles)]
            rec, truth = simulate(sample_scene(rng, p, dist), pre, seed=i)
            res = extract(rec)
            pred = clf.predict(res.as_array())
            own += pred.nearest == p.slug and pred.confidence >= 0.6 and pred.known
            rate += abs(res.features.flash_rate_hz / truth.blade_flash_rate_hz - 1) < 0.05
        print(f"{knob:24s} {own:>13d}/{n:<4d} {rate:>11d}/{n:<4d}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--n", type=int, default=60)
    ap.add_argument("--knobs", default=",".join(["none"] + [f.name for f in fields(NuisanceDistribution)]))
    ap.add_argument("--tip-weight", type=float, nargs=2, default=None,
                    help="tip_weight span to test instead of the default (e.g. 0 1)")
    a = ap.parse_args()
    run(a.preset, a.n, a.knobs.split(","), tuple(a.tip_weight) if a.tip_weight else None)


if __name__ == "__main__":
    main()
