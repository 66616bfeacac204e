"""Which evidence would make 1:1 verification hold in every world? (docs/benchmarks.md, "Held-out world")

Renders the same identity claims as `authn bench --worlds-only` (genuine, type spoofs between the
shipped profiles, unseen airframes claiming a registered serial; `CLAIM_SCENES` at a fixed SNR) in
three worlds: the training simulator, the same with a domain-randomisation draw per scene
(`sampling.NuisanceDistribution`) and the held-out model. Each return's features and the shipped
bundle's class probabilities are scored by `signatures.classify.verify` as shipped and with parts of the
evidence replaced by the truth, or left out:

    shipped                 measured estimates + classifier
    physics only            measured estimates, no classifier term
    true rate               the flown flash rate (std 2 %) + measured rest + classifier
    true rate, no clf       the same without the classifier term
    true rate+rotors, no clf  also rotors seen = the flown rotor count (std 10 %)

and prints, per world, the share of right decisions at the policy's threshold (LLR >= 0 accepts)
and the equal error rates (genuine against type spoofs / unseen). Nothing is fitted here: it
measures how far each piece of evidence carries, to say where estimator work pays.

`--dwells K` renders every scene K times with independent seeds (K dwells on one target: new
noise, blade phases and, in the shifted worlds, new nuisance draws) and scores each claim by the
sum of its dwells' LLRs (a dwell with nothing to verify adds 0): whether more dwells would
separate what one does not, i.e. whether one dwell's errors are noise or a bias of the world.

    python benchmarks/verification_evidence.py --preset paper --snr 10 --n 100
    python benchmarks/verification_evidence.py --preset paper --snr 10 --n 100 --dwells 4
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import asdict, replace

import numpy as np

from lab.bench.decisions import CLAIM_SCENES
from lab.bench.verification import UNVERIFIED, eer
from lab.bench.worlds import WORLD_CATEGORIES, _pair
from lab.accuracy import WORLDS, render_in_world
from signatures.features import extract
from lab.heldout import unseen_profiles
from signatures.classify.inference import classifier_for
from signatures.profiles import UavProfile, shipped_profiles
from signatures.radar import get_preset
from signatures.sim.sampling import sample_scene
from signatures.classify.verify import verify


#: Seed offset between the dwells of one scene.
DWELL_SEED_STEP = 7919


def collect(preset_name: str, snr: float, n: int, seed: int, dwells: int = 1) -> list[dict]:
    """One row per claim, world and dwell: features, physics, probabilities, truth. Dwell 0 is
    rendered with the seed a single-dwell run uses, so its rows are that run's."""
    preset = get_preset(preset_name)
    profiles: dict[str, UavProfile] = {**shipped_profiles(), **unseen_profiles()}
    slugs, unseen = list(shipped_profiles()), list(unseen_profiles())
    classifier, rows = None, []
    for c_idx, cat in enumerate(WORLD_CATEGORIES):
        rng = np.random.default_rng([seed, int(round(snr * 10)), c_idx])
        for i in range(n):
            flies, claims = _pair(cat, i, slugs, unseen)
            scene = sample_scene(rng, profiles[flies], replace(CLAIM_SCENES, snr_db=snr))
            first_seed = int(rng.integers(2**31))
            for world, dwell in ((w, d) for w in WORLDS for d in range(dwells)):
                sim_seed = (first_seed + DWELL_SEED_STEP * dwell) % 2**31
                rec, rate, _, _ = render_in_world(world, scene, preset, sim_seed)
                classifier = classifier or classifier_for(rec, None, "bench")
                result = extract(rec, expected_range_m=scene.range_m)
                pred = classifier.predict(result.as_array(), lambda r=result: r.rd_patch) if result.detected else None
                rows.append(dict(world=world, cat=cat, claim=i, dwell=dwell, flies=profiles[flies],
                                 claims=profiles[claims], rate=rate, detected=result.detected,
                                 estimates={**asdict(result.features), **result.physics},
                                 probs=dict(pred.probabilities) if pred else {}, known=bool(pred and pred.known),
                                 max_tip=rec.config.unambiguous_velocity_mps))
    return rows


def _truth(row: dict, rotors: bool) -> dict[str, float]:
    flown: UavProfile = row["flies"]
    flash = flown.blade_flash_rate_hz / flown.rotor_rate_hz * row["rate"]
    out = {**row["estimates"], "flash_rate_hz": flash, "flash_rate_std_hz": 0.02 * flash,
           "flash_score": max(row["estimates"]["flash_score"], 5.0)}
    if rotors:
        out.update(rotors_seen=float(flown.rotors), rotors_seen_std=0.1 * flown.rotors)
    return out


VARIANTS: dict[str, Callable[[dict], tuple[dict[str, float], bool]]] = {
    "shipped": lambda r: (r["estimates"], True),
    "physics only": lambda r: (r["estimates"], False),
    "true rate": lambda r: (_truth(r, False), True),
    "true rate, no clf": lambda r: (_truth(r, False), False),
    "true rate+rotors, no clf": lambda r: (_truth(r, True), False),
}


def score(row: dict, variant: str) -> float:
    if not row["detected"]:
        return UNVERIFIED
    estimates, with_classifier = VARIANTS[variant](row)
    v = verify(estimates, row["claims"], row["probs"] if with_classifier else None, row["max_tip"], row["known"])
    return v.llr if v.terms else UNVERIFIED


def claim_scores(rows: list[dict], variant: str, world: str, cat: str) -> list[float]:
    """Per claim of one world and category: the sum of its dwells' LLRs (a dwell with nothing to
    verify adds 0), or `UNVERIFIED` where no dwell had anything to verify."""
    dwells: dict[int, list[float]] = {}
    for r in rows:
        if r["world"] == world and r["cat"] == cat:
            dwells.setdefault(r["claim"], []).append(score(r, variant))
    verified = ([s for s in v if s != UNVERIFIED] for v in dwells.values())
    return [sum(v) if v else UNVERIFIED for v in verified]


def report(rows: list[dict]) -> None:
    print("| evidence | world | genuine accepted | type spoofs rejected | unseen rejected | EER spoof / unseen |")
    print("|---|---|---|---|---|---|")
    for variant in VARIANTS:
        for world in WORLDS:
            s = {c: claim_scores(rows, variant, world, c) for c in WORLD_CATEGORIES}
            gen = np.mean(np.array(s["genuine"]) >= 0.0)
            spoof, other = (np.mean(np.array(s[c]) < 0.0) for c in ("type_spoof", "unseen"))
            e1, e2 = eer(s["genuine"], s["type_spoof"]), eer(s["genuine"], s["unseen"])
            print(f"| {variant} | {world} | {gen:.0%} | {spoof:.0%} | {other:.0%} | {e1:.0%} / {e2:.0%} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--snr", type=float, default=10.0)
    ap.add_argument("--n", type=int, default=100, help="claims per category")
    ap.add_argument("--seed", type=int, default=101)
    ap.add_argument("--dwells", type=int, default=1, help="dwells per claim (independent renders), LLRs summed")
    args = ap.parse_args()
    if not math.isfinite(args.snr) or args.n < 2 or args.dwells < 1:
        ap.error("--snr must be finite, --n at least 2 and --dwells at least 1")
    rows = collect(args.preset, args.snr, args.n, args.seed, args.dwells)
    print(f"{args.preset}, {args.snr:g} dB, {args.n} claims per category, {args.dwells} dwell(s) each, "
          f"seed {args.seed}")
    report(rows)


if __name__ == "__main__":
    main()
