"""Site enrolment measured: decisions before and after `authn models enrol`, on a world
the shipped bundles were not built on, with enrolment and test scenes disjoint.

    python -m lab.bench.enrolment --sizes 5,10,30 --n 100 --snr 0,10 --world heldout --json out.json

A site's enrolment flights: `max(sizes)` recordings per shipped airframe at mixed SNR (0-20 dB),
rendered in `--world` from their own random stream; the first k of each airframe build the
site bundle of size k (the same code as the command: `authn.enrolment.site_sample`,
`signatures.train.enrol.enrol`). Test claims come from another stream: genuine, type spoofs and
unseen airframes (`lab.bench.worlds`), single dwells at each `--snr`, each checked by the real
`Checker` with the shipped bundle and with every site bundle. Genuine claims of a model the
site bundle calls radar-confusable with another registered one need a DRIP signature
(`radar-confusable-unsigned`): the table gives the genuine rate unsigned and "signed where
required" (counted accepted when that forbid is the only reason). Nothing is tuned on the test claims.

    python -m lab.bench.enrolment --track --sizes 30 --n 50 --snr 0,10 --world heldout --json out.json

`--track`: decisions over tracks. Each test claim is a track of up to `--dwells` (8)
dwells of one scene (`lab.bench.track`'s dwells: a new simulator seed per dwell, 1 s apart),
decided by `authn.track.decide_track` (the real Checker, policy and sequential test, stopping
early) with the shipped bundle and each site bundle (whose card now carries track-level pairwise
errors, and whose track checks use them); its first dwell is also checked alone (the single-dwell
figures beside). A site bundle is run twice: under the default policy (unsigned claims), and
under the default policy without `radar-confusable-unsigned` ("radar alone": what a claim with
a valid DRIP signature meets; for a type spoof, what radar does without the signature rule).
Each genuine scene is also flown with its Remote ID signed (DRIP, a keyed identity of the model)
and checked under the default policy: where the card calls the model radar-confusable, that claim
is verified against the confusable group (`authn.check`, docs/enrolment.md).
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
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.recording import write_recording

    pre = get_preset("paper")
    shipped = shipped_profiles()
    profiles = {**shipped, **unseen_profiles()}
    slugs, unseen = list(shipped), list(unseen_profiles())
    now = datetime.now(timezone.utc)
    out: dict = {"world": world, "sizes": list(sizes), "n": n, "snrs": list(snrs), "seed": seed, "enrolments": {},
                 "rates": {}, "eer": {}, "type_accuracy": {}}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        pool: list = []
        db_url, bundles = _enrol_sizes(root, sizes, world, seed, base_samples, out, log, pool_out=pool)
        checkers = {name: Checker(db_url, model=folder) for name, folder in bundles.items()}
        typers = _type_readers(bundles, pool, sizes, slugs, seed)
        trials: dict[tuple[str, float, str], list[tuple[str, tuple[str, ...], float]]] = defaultdict(list)
        typed: dict[str, list[bool]] = defaultdict(list)
        for snr, cat, flies, claims, scene, rng in _test_claims(seed, 2, snrs, n, slugs, unseen, profiles, log):
            rec = render_claim(world, scene, pre, int(rng.integers(2**31)),
                               Broadcast(serial=bench_serial(claims)), float(rng.uniform(0.0, 360.0)), now)
            path = write_recording(rec, root / "claim.h5")
            for name, checker in checkers.items():
                o = checker.evaluate(path)
                trials[(name, float(snr), cat)].append((o.decision, tuple(o.reasons),
                                                        verification_score(o.to_json()["radar"])))
            if cat == "genuine":
                x = site_sample(path, flies, None, rec)[0].features[None, :]
                for name, read in typers.items():
                    typed[f"{name}/{snr:g}"].append(read(x) == flies)
    out["type_accuracy"] = {k: round(sum(v) / len(v), 4) for k, v in typed.items()}
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


def _type_readers(bundles: dict[str, Path | None], pool: list, sizes: tuple[int, ...], slugs: list[str],
                  seed: int) -> dict[str, object]:
    """Name -> (feature row -> the airframe type it reads): each site bundle's ensemble (its most
    probable of the enrolled types), and, as the baseline a site could fit without us, a plain
    random forest on the site's own k recordings per airframe alone ('plain forest k')."""
    from sklearn.ensemble import RandomForestClassifier

    from signatures.classify.inference import Classifier, bundle_dir

    readers: dict[str, object] = {}
    for name, folder in bundles.items():
        clf = Classifier(folder or bundle_dir("paper"))
        cols = [i for i, c in enumerate(clf.classes) if c in slugs]
        readers[name] = lambda x, clf=clf, cols=cols: clf.classes[cols[int(np.argmax(clf.ensemble_proba(x)[0, cols]))]]
    for k in sizes:
        X = np.array([s.features for i, s in pool if i < k])
        y = np.array([s.model for i, s in pool if i < k])
        rf = RandomForestClassifier(n_estimators=300, random_state=seed, n_jobs=1).fit(np.nan_to_num(X), y)
        readers[f"plain forest {k}"] = lambda x, rf=rf: str(rf.predict(np.nan_to_num(x))[0])
    return readers


def _enrol_sizes(root: Path, sizes: tuple[int, ...], world: str, seed: int, base_samples: int, out: dict,
                 log, site_bands: bool = False, calibrate: bool = False,
                 keys: dict | None = None, pool_out: list | None = None) -> tuple[str, dict[str, Path | None]]:
    """The bench registry and the site bundles: `max(sizes)` enrolment recordings per shipped
    airframe at 0-20 dB from the enrolment stream (a generator per recording, so that recording i
    of an airframe is the same whatever `sizes` asks for), the first k of each enrolled at each size k
    (with the check's sequential test: the card's track-level errors) as `authn models enrol`
    does; with `site_bands` also with site physics bands ('site-k site bands'), with `calibrate` also with
    the site's score calibration applied ('site-k calibrated'); `keys` (slug -> DRIP key): also a
    keyed identity per slug (`register_identities`); `pool_out`: extended with (index within its
    airframe, site sample) of every enrolment recording. (database URL, bundles)."""
    from authn.enrolment import site_sample
    from authn.scenario import Broadcast
    from authn.sprt import Sprt
    from registry.dbapi import Database
    from signatures.train.enrol import EnrolOptions, enrol
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.recording import write_recording
    from signatures.sim.sampling import sample_scene

    pre = get_preset("paper")
    shipped = shipped_profiles()
    now = datetime.now(timezone.utc)
    db_url = f"sqlite:///{root / 'bench.sqlite3'}"
    register_identities(db_url, keys)
    db = Database(db_url)
    pool = []
    for s_idx, slug in enumerate(shipped):
        for i in range(max(sizes)):
            rng = np.random.default_rng([seed, 1, s_idx, i])  # the enrolment stream: one per recording
            scene = sample_scene(rng, shipped[slug], replace(CLAIM_SCENES, snr_db=(0.0, 20.0)))
            rec = render_claim(world, scene, pre, int(rng.integers(2**31)), Broadcast(serial=bench_serial(slug)),
                               float(rng.uniform(0.0, 360.0)), now)
            path = write_recording(rec, root / "enrol" / f"{slug}-{i:03d}.h5")
            pool.append((i, site_sample(path, slug, db, rec)[0]))
    if pool_out is not None:
        pool_out.extend(pool)
    bundles: dict[str, Path | None] = {"shipped": None}
    # (site bands, score calibration): the default is what `authn models enrol` does (None: applied
    # where the site's cross-validated claims say it pays); --calibrate adds one with it forced on
    variants = [(False, None), *([(True, None)] if site_bands else []), *([(False, True)] if calibrate else [])]
    for k, (bands, cal) in ((k, v) for k in sizes for v in variants):
        t0 = time.perf_counter()
        suffix = " site bands" if bands else " calibrated" if cal else ""
        name = f"site-{k}{suffix}"
        folder = root / "models" / name.replace(" ", "-")
        card = enrol([s for i, s in pool if i < k], shipped, pre, folder,
                     EnrolOptions(name=name.replace(" ", "-"), seed=seed, n_sim=base_samples, sprt=Sprt(),
                                  physics_bands=bands, score_calibration=cal))
        e = card["enrolment"]
        out["enrolments"][f"{k}{suffix}" if suffix else k] = {
            "seconds": round(time.perf_counter() - t0, 1), "confusable_pairs": e["confusable_pairs"],
            "confusable_pairs_tracks": e["confusable_pairs_tracks"],
            "pairwise": {"/".join(p["models"]): p["single_dwell"] for p in e["pairwise"]},
            "pairwise_tracks": {"/".join(p["models"]): p["tracks"] for p in e["pairwise"]},
            "tracks": e["tracks"], "threshold": e["threshold"], "bands": e["bands"], "calibration": e["calibration"],
            "cv_accuracy": card["metrics"]["validation"]}
        log(f"enrolled {name} in {time.perf_counter() - t0:.1f} s; confusable {e['confusable_pairs']}, "
            f"over tracks {e['confusable_pairs_tracks']}; bands {e['bands']}; calibration {e['calibration']['coef']} "
            f"{e['calibration']['intercept']:.3f}, genuine dwell {e['calibration']['evidence_per_genuine_dwell']}")
        bundles[name] = folder
    return db_url, bundles


def _test_claims(seed: int, stream: int, snrs: tuple[float, ...], n: int, slugs: list[str], unseen: list[str],
                 profiles: dict, log=print):
    """The test claims of one random stream, disjoint from the enrolment stream ([seed, 1, ...]): for each
    SNR and category, n (snr, category, flown, claimed, scene, rng), the generator drawing on; a
    progress line after each SNR and category."""
    from signatures.sim.sampling import sample_scene

    for s_idx, snr in enumerate(snrs):
        for c_idx, cat in enumerate(WORLD_CATEGORIES):
            rng = np.random.default_rng([seed, stream, s_idx, c_idx])
            for i in range(n):
                flies, claims = _pair(cat, i, slugs, unseen)
                scene = sample_scene(rng, profiles[flies], replace(CLAIM_SCENES, snr_db=float(snr)))
                yield snr, cat, flies, claims, scene, rng
            log(f"{snr:g} dB {cat}: {n} claims")


def _radar_alone_policy(root: Path) -> Path:
    """The default policy without `radar-confusable-unsigned`: what a validly signed claim meets."""
    import re

    text = (Path(__file__).resolve().parents[2] / "authn" / "policies" / "default.cedar").read_text()
    cut = re.sub(r'@id\("radar-confusable-unsigned"\)\s*forbid[^;]*;', "", text)
    if cut == text:
        raise RuntimeError("default.cedar: no radar-confusable-unsigned forbid to leave out")
    path = root / "radar-alone.cedar"
    path.write_text(cut)
    return path


def run_tracks(sizes: tuple[int, ...], n: int, snrs: tuple[float, ...], world: str, seed: int,
               base_samples: int, dwells: int = 8, log=print, site_bands: bool = False,
               calibrate: bool = False) -> dict:
    """Enrol at each size; n tracks per category and SNR, decided with the shipped bundle and each
    site bundle (default policy and radar alone); their first dwells checked alone beside them. Each
    genuine scene is also flown with its Remote ID signed (DRIP, the keyed identity of the model:
    category `genuine_signed`) and checked under the default policy."""
    from authn import uakeys
    from authn.check import CheckInput, Checker
    from authn.track import decide_track
    from lab.bench.decisions import drip_broadcast, keyed_serial
    from lab.bench.track import _lazy_dwell
    from lab.heldout import unseen_profiles
    from signatures.profiles import shipped_profiles

    shipped = shipped_profiles()
    profiles = {**shipped, **unseen_profiles()}
    slugs, unseen = list(shipped), list(unseen_profiles())
    out: dict = {"world": world, "sizes": list(sizes), "n": n, "snrs": list(snrs), "seed": seed, "dwells": dwells,
                 "enrolments": {}, "tracks": {}, "single": {}, "pairs": {}}
    rows: dict[tuple[str, str, float, str], list[tuple[str, tuple[str, ...], int]]] = defaultdict(list)
    single: dict[tuple[str, str, float, str], list[tuple[str, tuple[str, ...]]]] = defaultdict(list)
    pairs: dict[tuple[str, str, float, str, str], list[str]] = defaultdict(list)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        keys = {slug: uakeys.generate() for slug in slugs}
        db_url, bundles = _enrol_sizes(root, sizes, world, seed, base_samples, out, log, site_bands, calibrate, keys)
        alone = _radar_alone_policy(root)
        checkers = {"shipped": Checker(db_url)}
        for name, folder in bundles.items():
            if folder is not None:
                checkers[name] = Checker(db_url, model=folder)
                checkers[f"{name} radar alone"] = Checker(db_url, policy_path=alone, model=folder)
        for snr, cat, flies, claims, scene, rng in _test_claims(seed, 3, snrs, n, slugs, unseen, profiles, log):
            az, base = float(rng.uniform(0.0, 360.0)), int(rng.integers(2**31 - dwells))
            start = datetime.now(timezone.utc)
            track = [_lazy_dwell(scene, "paper", base + j, bench_serial(claims), az, start, j, world)
                     for j in range(dwells)]
            runs = [(cat, track, checkers)]
            if cat == "genuine":  # the same scene and seeds, its Remote ID signed by the model's keyed identity
                signed = drip_broadcast("drip_genuine", keyed_serial(claims), 0.0, keys[claims], keys[claims])
                runs.append(("genuine_signed", [_lazy_dwell(scene, "paper", base + j, keyed_serial(claims), az, start,
                                                            j, world, broadcast=signed) for j in range(dwells)],
                             {k: c for k, c in checkers.items() if not k.endswith("radar alone")}))
            for category, dwells_of, by_name in runs:
                for name, checker in by_name.items():
                    o = decide_track(checker, dwells_of)
                    rows[(name, world, float(snr), category)].append((o.decision, tuple(o.reasons), o.dwells_used))
                    pairs[(name, float(snr), category, flies, claims)].append(o.decision)
                    one = checker.decide_one(CheckInput.recording(dwells_of[0].load()[0], None))
                    single[(name, world, float(snr), category)].append((one.decision, tuple(one.reasons)))
    for key, ts in rows.items():
        name, _, snr, cat = key
        want = "accept" if cat.startswith("genuine") else "reject"
        k = f"{name}/{snr:g}/{cat}"
        used = sorted(t[2] for t in ts)
        out["tracks"][k] = {"right": _share([(d, r, 0) for d, r, _ in ts], lambda d, r, want=want: d == want),
                            "median_dwells": float(np.median(used)), "n": len(ts),
                            "confusable_unsigned": _share([(d, r, 0) for d, r, _ in ts],
                                                          lambda d, r: CONFUSABLE in r)}
        out["single"][k] = {"right": _share([(d, r, 0) for d, r in single[key]], lambda d, r, want=want: d == want),
                            "n": len(single[key])}
    for (name, snr, cat, flies, claims), ds in pairs.items():
        want = "accept" if cat.startswith("genuine") else "reject"
        signed = " signed" if cat == "genuine_signed" else ""
        out["pairs"][f"{name}/{snr:g}/{flies}->{claims}{signed}"] = {
            "right": round(sum(d == want for d in ds) / len(ds), 4), "n": len(ds), "category": cat}
    return out


def dwell_evidence(size: int, n: int, dwells: int, snrs: tuple[float, ...], world: str, seed: int,
                   base_samples: int, log=print) -> dict:
    """What one dwell is worth with each site bundle (enrolled at `size`, uncalibrated and with its
    score calibration): n scenes per category (genuine, type spoof) and SNR, `dwells` dwells each (a
    new simulator seed per dwell, `lab.bench.track`), every dwell checked alone. Per bundle, SNR and
    category: the share of dwells with a target detected, of those with the physics term abstained,
    the mean verification LLR and the mean track increment (capped, `Sprt.increment`), and the
    intra-class correlation of the capped LLRs within one (flown, claimed) pair (`lab.bench.track.icc`:
    the dwell correlation the track's discount needs, re-measured on these scores)."""
    from authn.check import CheckInput, Checker
    from authn.sprt import Sprt
    from lab.bench.track import _pair as track_pair, icc, track_recordings
    from signatures.profiles import shipped_profiles
    from signatures.sim.sampling import sample_scene

    shipped = shipped_profiles()
    slugs = list(shipped)
    sprt = Sprt()
    out: dict = {"world": world, "size": size, "n": n, "dwells": dwells, "snrs": list(snrs), "seed": seed,
                 "enrolments": {}, "rows": {}}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        db_url, bundles = _enrol_sizes(root, (size,), world, seed, base_samples, out, log, calibrate=True)
        checkers = {name: Checker(db_url, model=folder) for name, folder in bundles.items() if folder is not None}
        for s_idx, snr in enumerate(snrs):
            for c_idx, cat in enumerate(("genuine", "type_spoof")):
                rng = np.random.default_rng([seed, 4, s_idx, c_idx])  # a stream of its own
                per: dict[str, dict] = {name: {"seen": 0, "detected": 0, "abstained": 0, "llr": [], "inc": [],
                                               "pairs": defaultdict(list)} for name in checkers}
                for i in range(n):
                    flies, claims = track_pair(cat, i, slugs)
                    scene = sample_scene(rng, shipped[flies], replace(CLAIM_SCENES, snr_db=float(snr)))
                    az, base = float(rng.uniform(0.0, 360.0)), int(rng.integers(2**31 - dwells))
                    recs = track_recordings(scene, "paper", list(range(base, base + dwells)), bench_serial(claims),
                                            az, world=world)
                    for name, checker in checkers.items():
                        acc, group = per[name], []
                        for rec in recs:
                            o = checker.decide_one(CheckInput.recording(rec, None))
                            acc["seen"] += 1
                            v = o.radar.verification if o.radar is not None and o.radar.detected else None
                            if o.radar is not None and o.radar.detected:
                                acc["detected"] += 1
                            if v is None or not v.terms:
                                continue
                            acc["abstained"] += v.physics_abstained
                            acc["llr"].append(v.llr)
                            acc["inc"].append(sprt.increment(v.llr, not v.physics_abstained))
                            group.append(max(-sprt.cap_nats, min(sprt.cap_nats, v.llr)))
                        acc["pairs"][(flies, claims)].append(group)
                for name, acc in per.items():
                    pair_icc = [(sum(map(len, gs)), icc(gs)) for gs in acc["pairs"].values()
                                if sum(len(g) >= 2 for g in gs) >= 2]
                    out["rows"][f"{name}/{snr:g}/{cat}"] = {
                        "dwells": acc["seen"], "detected": round(acc["detected"] / max(acc["seen"], 1), 4),
                        "physics_abstained": round(acc["abstained"] / max(acc["detected"], 1), 4),
                        "mean_llr": round(float(np.mean(acc["llr"])), 4) if acc["llr"] else None,
                        "mean_increment": round(float(np.mean(acc["inc"])), 4) if acc["inc"] else None,
                        "icc": (round(sum(w * v for w, v in pair_icc) / sum(w for w, _ in pair_icc), 4)
                                if pair_icc else None)}
                log(f"{world} {snr:g} dB {cat}: {n} scenes x {dwells} dwells")
    return out


def evidence_table(doc: dict) -> str:
    """Markdown: per bundle, SNR and category, what a dwell is worth."""
    lines = ["| world | bundle | SNR | claims | detected | physics abstained | mean LLR | mean increment | "
             "dwell correlation (ICC) |", "|---|---|---|---|---|---|---|---|---|"]
    for key, r in doc["rows"].items():
        name, snr, cat = key.split("/")
        lines.append(f"| {doc['world']} | {name} | {snr} dB | {cat} | {r['detected']:.0%} | "
                     f"{r['physics_abstained']:.0%} | {r['mean_llr']} | {r['mean_increment']} | {r['icc']} |")
    return "\n".join(lines)


def track_table(doc: dict) -> str:
    """Markdown: per bundle and SNR, tracks right (single dwells right) per category."""
    lines = ["| world | bundle | SNR | genuine accepted | genuine signed accepted | type spoofs rejected | "
             "unseen rejected | median dwells (genuine / signed / spoof / unseen) |",
             "|---|---|---|---|---|---|---|---|"]
    names = list(dict.fromkeys(k.split("/")[0] for k in doc["tracks"]))
    cats = ("genuine", "genuine_signed", "type_spoof", "unseen")
    none = {"right": float("nan"), "median_dwells": float("nan")}
    for name in names:
        for snr in doc["snrs"]:
            k = f"{name}/{snr:g}"
            t = [doc["tracks"].get(f"{k}/{c}", none) for c in cats]  # radar alone: no signed run
            sd = [doc["single"].get(f"{k}/{c}", none) for c in cats]
            cells = [f"{a['right']:.1%} ({b['right']:.1%})" for a, b in zip(t, sd)]
            med = " / ".join(f"{a['median_dwells']:g}" for a in t)
            lines.append(f"| {doc['world']} | {name} | {snr:g} dB | " + " | ".join(cells) + f" | {med} |")
    return "\n".join(lines)


def pair_table(doc: dict) -> str:
    """Markdown: per bundle, SNR and (flown -> claimed) pair, the share of right track decisions."""
    lines = ["| world | bundle | SNR | flown -> claimed | category | tracks right | n |",
             "|---|---|---|---|---|---|---|"]
    for key, row in sorted(doc["pairs"].items()):
        name, snr, pair = key.split("/")
        lines.append(f"| {doc['world']} | {name} | {snr} dB | {pair} | {row['category']} | {row['right']:.1%} | "
                     f"{row['n']} |")
    return "\n".join(lines)


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
    acc = doc.get("type_accuracy") or {}
    if acc:
        snrs = " | ".join(f"{s:g} dB" for s in doc["snrs"])
        lines += ["", f"| reads the type of genuine single dwells | {snrs} |", "|---|" + "---|" * len(doc["snrs"])]
        for name in dict.fromkeys(k.rsplit("/", 1)[0] for k in acc):
            lines.append(f"| {name} | " + " | ".join(f"{acc[f'{name}/{s:g}']:.1%}" for s in doc["snrs"]) + " |")
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
    ap.add_argument("--track", action="store_true", help="test claims as tracks (authn check --track) with the "
                                                        "single-dwell figures of their first dwells beside")
    ap.add_argument("--dwells", type=int, default=8, help="with --track: dwells per track at most")
    ap.add_argument("--pairs", action="store_true", help="with --track: also the per-pair rows")
    ap.add_argument("--site-bands", action="store_true", help="with --track: also each site bundle enrolled "
                                                              "with site physics bands (models enrol --site-bands)")
    ap.add_argument("--dwell-evidence", action="store_true",
                    help="what one dwell is worth with the site bundle of the largest size, uncalibrated and "
                         "calibrated: detection, physics abstained, mean LLR and increment, dwell correlation "
                         "(--n scenes x --dwells dwells per category and SNR)")
    ap.add_argument("--calibrate", action="store_true",
                    help="with --track: also each site bundle enrolled with its score calibration applied "
                         "(models enrol --calibrate on)")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    args = (tuple(int(s) for s in a.sizes.split(",")), a.n, tuple(float(s) for s in a.snr.split(",")), a.world,
            a.seed, a.base_samples)
    say = lambda m: print(m, file=sys.stderr)  # noqa: E731
    if a.dwell_evidence:
        doc = dwell_evidence(max(args[0]), a.n, a.dwells, args[2], a.world, a.seed, a.base_samples, log=say)
        doc["seconds"] = round(time.perf_counter() - t0, 1)
        if a.json:
            a.json.write_text(json.dumps(doc, indent=1))
        print(evidence_table(doc))
        return 0
    doc = (run_tracks(*args, dwells=a.dwells, log=say, site_bands=a.site_bands, calibrate=a.calibrate) if a.track
           else run(*args, log=say))
    doc["seconds"] = round(time.perf_counter() - t0, 1)
    doc["cpus"] = os.cpu_count()
    if a.json:
        a.json.write_text(json.dumps(doc, indent=1))
    print(track_table(doc) if a.track else table(doc))
    if a.track and a.pairs:
        print()
        print(pair_table(doc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
