"""Site enrolment measured (issue 32): decisions before and after `authn models enrol`, on a world
the shipped bundles were not built on, with enrolment and test scenes disjoint.

    python -m lab.bench.enrolment --sizes 5,10,30 --n 100 --snr 0,10 --world heldout --json out.json

A site's enrolment flights: `max(sizes)` recordings per shipped airframe at mixed SNR (0-20 dB),
rendered in `--world` from their own random stream; the first k of each airframe build the
site bundle of size k (the same code as the command: `authn.enrolment.site_sample`,
`signatures.enrol.enrol`). Test claims come from another stream: genuine, type spoofs and
unseen airframes (`lab.bench.worlds`), single dwells at each `--snr`, each checked by the real
`Checker` with the shipped bundle and with every site bundle. Genuine claims of a model the
site bundle calls radar-confusable with another registered one need a DRIP signature
(`radar-confusable-unsigned`): the table gives the genuine rate unsigned and "signed where
required" (counted accepted when that forbid is the only reason). Nothing is tuned on the test claims.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections import defaultdict
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from lab.bench.decisions import CLAIM_SCENES, bench_serial, register_identities
from lab.bench.verification import eer, verification_score
from lab.bench.worlds import WORLD_CATEGORIES, _pair, render_claim

CONFUSABLE = "radar-confusable-unsigned"


def run(sizes: tuple[int, ...], n: int, snrs: tuple[float, ...], world: str, seed: int,
        base_samples: int, log=print) -> dict:
    """Enrol at each size, check the test claims with the shipped and each site bundle."""
    from authn.check import Checker
    from authn.enrolment import site_sample
    from authn.scenario import Broadcast
    from lab.heldout import unseen_profiles
    from registry.dbapi import Database
    from signatures.enrol import enrol
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.recording import write_recording
    from signatures.sampling import sample_scene

    pre = get_preset("paper")
    shipped = shipped_profiles()
    profiles = {**shipped, **unseen_profiles()}
    slugs, unseen = list(shipped), list(unseen_profiles())
    now = datetime.now(timezone.utc)
    out: dict = {"world": world, "sizes": list(sizes), "n": n, "snrs": list(snrs), "seed": seed, "enrolments": {},
                 "rates": {}, "eer": {}}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        db_url = f"sqlite:///{root / 'bench.sqlite3'}"
        register_identities(db_url)
        db = Database(db_url)
        rng = np.random.default_rng([seed, 1])  # the enrolment stream
        pool = []
        for slug in slugs:
            for i in range(max(sizes)):
                scene = sample_scene(rng, shipped[slug], replace(CLAIM_SCENES, snr_db=(0.0, 20.0)))
                rec = render_claim(world, scene, pre, int(rng.integers(2**31)), Broadcast(serial=bench_serial(slug)),
                                   float(rng.uniform(0.0, 360.0)), now)
                path = write_recording(rec, root / "enrol" / f"{slug}-{i:03d}.h5")
                pool.append((i, site_sample(path, slug, db, rec)[0]))
        bundles: dict[str, Path | None] = {"shipped": None}
        for k in sizes:
            t0 = time.perf_counter()
            folder = root / "models" / f"site-{k}"
            card = enrol([s for i, s in pool if i < k], shipped, pre, folder, name=f"site-{k}", seed=seed,
                         n_sim=base_samples)
            e = card["enrolment"]
            out["enrolments"][k] = {"seconds": round(time.perf_counter() - t0, 1), "confusable_pairs":
                                    e["confusable_pairs"], "pairwise": {"/".join(p["models"]): p["single_dwell"]
                                                                        for p in e["pairwise"]},
                                    "threshold": e["threshold"], "cv_accuracy": card["metrics"]["validation"]}
            log(f"enrolled {k} per model in {out['enrolments'][k]['seconds']} s; confusable {e['confusable_pairs']}")
            bundles[f"site-{k}"] = folder
        checkers = {name: Checker(db_url, model=folder) for name, folder in bundles.items()}
        trials: dict[tuple[str, float, str], list[tuple[str, tuple[str, ...], float]]] = defaultdict(list)
        for s_idx, snr in enumerate(snrs):
            for c_idx, cat in enumerate(WORLD_CATEGORIES):
                rng = np.random.default_rng([seed, 2, s_idx, c_idx])  # the test stream: disjoint from enrolment
                for i in range(n):
                    flies, claims = _pair(cat, i, slugs, unseen)
                    scene = sample_scene(rng, profiles[flies], replace(CLAIM_SCENES, snr_db=float(snr)))
                    rec = render_claim(world, scene, pre, int(rng.integers(2**31)),
                                       Broadcast(serial=bench_serial(claims)), float(rng.uniform(0.0, 360.0)), now)
                    path = write_recording(rec, root / "claim.h5")
                    for name, checker in checkers.items():
                        o = checker.evaluate(path)
                        trials[(name, float(snr), cat)].append((o.decision, tuple(o.reasons),
                                                                verification_score(o.to_json()["radar"])))
            log(f"checked {snr:g} dB")
    for (name, snr, cat), ts in trials.items():
        key = f"{name}/{snr:g}/{cat}"
        if cat == "genuine":
            out["rates"][key] = {"accepted": _share(ts, lambda d, r: d == "accept"),
                                 "accepted_signed_where_required": _share(
                                     ts, lambda d, r: d == "accept" or r == (CONFUSABLE,)),
                                 "n": len(ts)}
        else:
            out["rates"][key] = {"rejected": _share(ts, lambda d, r: d == "reject"),
                                 "rejected_by_radar": _share(ts, lambda d, r: d == "reject" and r != (CONFUSABLE,)),
                                 "n": len(ts)}
            g = trials[(name, snr, "genuine")]
            out["eer"][key] = round(eer([t[2] for t in g], [t[2] for t in ts]), 4)
    return out


def _share(ts, ok) -> float:
    return round(sum(ok(d, r) for d, r, _ in ts) / len(ts), 4)


def table(doc: dict) -> str:
    """Markdown: one row per bundle and SNR."""
    lines = ["| bundle | SNR | genuine accepted (unsigned / signed where required) | type spoofs rejected "
             "(all / by radar alone) | unseen rejected | EER type spoof / unseen |", "|---|---|---|---|---|---|"]
    names = ["shipped", *(f"site-{k}" for k in doc["sizes"])]
    for name in names:
        for snr in doc["snrs"]:
            k = f"{name}/{snr:g}"
            g, t, u = doc["rates"][f"{k}/genuine"], doc["rates"][f"{k}/type_spoof"], doc["rates"][f"{k}/unseen"]
            lines.append(f"| {name} | {snr:g} dB | {g['accepted']:.1%} / {g['accepted_signed_where_required']:.1%} | "
                         f"{t['rejected']:.1%} / {t['rejected_by_radar']:.1%} | {u['rejected']:.1%} | "
                         f"{doc['eer'][k + '/type_spoof']:.1%} / {doc['eer'][k + '/unseen']:.1%} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lab.bench.enrolment", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="5,10,30", help="enrolment recordings per airframe, comma-separated")
    ap.add_argument("--n", type=int, default=100, help="test claims per category and SNR")
    ap.add_argument("--snr", default="0,10", help="test SNRs, dB")
    ap.add_argument("--world", default="heldout", choices=("heldout", "training"))
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--base-samples", type=int, default=1500)
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    doc = run(tuple(int(s) for s in a.sizes.split(",")), a.n, tuple(float(s) for s in a.snr.split(",")), a.world,
              a.seed, a.base_samples, log=lambda m: print(m, file=sys.stderr))
    doc["seconds"] = round(time.perf_counter() - t0, 1)
    doc["cpus"] = os.cpu_count()
    if a.json:
        a.json.write_text(json.dumps(doc, indent=1))
    print(table(doc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
