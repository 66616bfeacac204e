"""Decisions over 2 s tracks of back-to-back `paper` dwells, no enrolment,
decided by `authn.track.decide_track` (the real Checker, policy and sequential test, stopping
early), per (airframe flown, model claimed) pair, in the held-out world and the training
simulator; and the per-dwell diagnosis of genuine claims (docs/tracks.md, "2 s tracks, no enrolment").

    python -m lab.bench.track_accuracy --world heldout --world training --snr 10 --snr 0 --n 16
    python -m lab.bench.track_accuracy --diagnose --world heldout --snr 10 --snr 0 --n 12 --dwells 8 --json d.json
    python -m lab.bench.track_accuracy --what-if d.json
    python -m lab.bench.track_accuracy --icc d.json [--first 5] [--rho-terms 0.3,0.4]

Which pairs the physics can separate (`separable`): the claimed and the flown airframe's nominal
blade-flash rates lie outside each other's `signatures.classify.verify.RATE_BAND`, or their rotor counts
differ by 2 or more. Claimed models are the shipped profiles (the bench registry's); flown ones
the shipped and `lab.heldout.unseen_profiles()`. Rows holding pairs that `lab.bench.reach` shows
no rule separates (`OUT_OF_REACH`) are printed again without them. Nothing here trains or tunes
anything.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime, timezone
from typing import Any, NamedTuple

import numpy as np

from lab.bench.decisions import CLAIM_SCENES, bench_serial, is_right
from signatures.profiles import UavProfile, shipped_profiles
from signatures.radar import get_preset
from signatures.sim.sampling import sample_scene

#: A track: 2 s of a target, its dwells back to back.
TRACK_SECONDS = 2.0
CATEGORIES = ("genuine", "type_spoof", "unseen")
TARGETS = {("genuine", 10.0): 0.97, ("genuine", 0.0): 0.95, ("type_spoof", 10.0): 0.97, ("type_spoof", 0.0): 0.95,
           ("unseen", 10.0): 0.97, ("unseen", 0.0): 0.95}


def all_profiles() -> dict[str, UavProfile]:
    from lab.heldout import unseen_profiles

    return {**shipped_profiles(), **unseen_profiles()}


def separable(flown: UavProfile, claimed: UavProfile) -> list[str]:
    """Why the physics can tell `flown` from `claimed` ([] : it cannot, by this rule): "rate" when
    each nominal blade-flash rate lies outside the other's RATE_BAND (flown rotors turn at 0.8-1.2x
    nominal, so the bands of the two do not hold each other's nominal), "rotors" when the rotor
    counts differ by 2 or more (rotors seen is counted within `ROTOR_BAND` of the claim)."""
    from signatures.classify.verify import RATE_BAND

    fa, fb = flown.blade_flash_rate_hz, claimed.blade_flash_rate_hz
    why = []
    if not (RATE_BAND[0] <= fa / fb <= RATE_BAND[1]) and not (RATE_BAND[0] <= fb / fa <= RATE_BAND[1]):
        why.append("rate")
    if abs(flown.rotors - claimed.rotors) >= 2:
        why.append("rotors")
    return why


def pairs() -> list[tuple[str, str, str, list[str]]]:
    """(category, flown, claimed, why separable) of every claim the bench makes: each shipped model
    claiming itself, every ordered pair of shipped models, every unseen airframe claiming each."""
    from lab.heldout import unseen_profiles

    shipped, unseen, prof = list(shipped_profiles()), list(unseen_profiles()), all_profiles()
    out: list[tuple[str, str, str, list[str]]] = [("genuine", s, s, []) for s in shipped]
    out += [("type_spoof", a, b, separable(prof[a], prof[b])) for a in shipped for b in shipped if a != b]
    out += [("unseen", a, b, separable(prof[a], prof[b])) for a in unseen for b in shipped]
    return out


# --- one worker's state ------------------------------------------------------------------------

_STATE: dict[str, Any] = {}


def _recording_checker() -> Any:
    """A Checker on a temporary bench registry that keeps what each verification was given."""
    from authn.check import Checker
    from lab.bench.decisions import register_identities

    class Recorder(Checker):
        def _verify(self, feats: Any, pred: Any, claimed: Any, rec: Any, *more: Any, **kw: Any) -> Any:  # type: ignore[override]
            v = Checker._verify(feats, pred, claimed, rec, *more, **kw)
            self.seen.append({"features": {**asdict(feats.features), **feats.physics}, "label": pred.label,
                              "known": bool(pred.known), "probabilities": dict(pred.probabilities),
                              "simulation": rec.simulation,
                              "verification": None if v is None else v.to_json()})
            return v

    tmp = tempfile.mkdtemp(prefix="track-accuracy-")
    db = f"sqlite:///{os.path.join(tmp, 'bench.sqlite3')}"
    register_identities(db)
    checker = Recorder(db)
    checker.seen = []  # type: ignore[attr-defined]
    return checker


def _checker() -> Any:
    if "checker" not in _STATE:
        _STATE["checker"] = _recording_checker()
    return _STATE["checker"]


def _scene_and_draws(seed: int, world_idx: int, snr: float, pair_idx: int, i: int,
                     flies: str) -> tuple[Any, float, int]:
    """The scene of track i of a pair (the same in every world: `world_idx` is not drawn on)."""
    del world_idx
    rng = np.random.default_rng([seed, int(round(snr * 10)) + 1000, pair_idx, i, 31])
    scene = sample_scene(rng, all_profiles()[flies], replace(CLAIM_SCENES, snr_db=float(snr)))
    return scene, float(rng.uniform(0.0, 360.0)), int(rng.integers(2**31 - 1000))


def _split_terms(features: dict[str, float], claimed: UavProfile, verification: dict | None,
                 max_tip: float) -> dict[str, float | None]:
    """The physics term taken apart: rate alone, what the rotors-seen ratio adds, what the blade
    ratio adds (`signatures.classify.verify._physics` on the estimates with the others masked)."""
    from signatures.classify.verify import _physics

    def phys(f: dict[str, float]) -> float | None:
        r = _physics(f, claimed, max_tip)
        return None if r is None else r[0]

    rate = phys({**features, "rotors_seen": 0.0, "tip_speed_mps": 0.0})
    with_rotors = phys({**features, "tip_speed_mps": 0.0})
    full = phys(features)
    terms = (verification or {}).get("terms", {})
    return {"rate": rate, "rotors": None if with_rotors is None or rate is None or with_rotors == rate else
            with_rotors - rate,
            "blade": None if full is None or with_rotors is None or full == with_rotors else full - with_rotors,
            "physics": terms.get("physics"), "classifier": terms.get("classifier")}


def _dwell_record(seen: dict, claimed: UavProfile, flown: UavProfile, max_tip: float) -> dict[str, Any]:
    f = seen["features"]
    truth = json.loads(seen["simulation"]).get("truth", {}) if seen["simulation"] else {}
    pattern = truth.get("pattern_rates_hz") or []
    v = seen["verification"]
    return {"label": seen["label"], "known": seen["known"], "llr": None if v is None else v["llr"],
            "probabilities": {k: round(float(p), 6) for k, p in seen.get("probabilities", {}).items()},
            "terms": _split_terms(f, claimed, v, max_tip),
            "flash_rate_hz": float(f.get("flash_rate_hz", 0.0)),
            "flash_rate_std_hz": float(f.get("flash_rate_std_hz", 0.0)),
            "flash_score": float(f.get("flash_score", 0.0)), "rotors_seen": float(f.get("rotors_seen", 0.0)),
            "rotors_seen_std": float(f.get("rotors_seen_std", 0.0)), "tip_aliased": float(f.get("tip_aliased", 0.0)),
            "true_flash_rate_hz": float(np.mean(pattern)) if pattern else None,
            "true_rate_spread": float((max(pattern) - min(pattern)) / np.mean(pattern)) if pattern else None,
            "true_rotor_rate_hz": truth.get("rotor_rate_hz"), "nominal_flash_rate_hz": claimed.blade_flash_rate_hz,
            "flown_nominal_flash_rate_hz": flown.blade_flash_rate_hz, "claimed_rotors": claimed.rotors,
            "flown_rotors": flown.rotors}


@dataclass
class TrackResult:
    world: str
    snr_db: float
    category: str
    flies: str
    claims: str
    separable: list[str]
    decision: str
    reasons: list[str]
    dwells_used: int
    dwells: int
    llr: float
    seconds: float
    per_dwell: list[dict[str, Any]] = field(default_factory=list)


def _one_track(job: tuple) -> TrackResult:
    """Track i of a pair in a world at an SNR, decided by `decide_track` (early stop as `authn check --track`)."""
    from authn.track import decide_track
    from lab.bench.track import _lazy_dwell

    preset, world, w_idx, snr, seed, p_idx, (cat, flies, claims, why), i, max_dwells = job
    t0 = time.perf_counter()
    checker = _checker()
    checker.seen.clear()
    pre = get_preset(preset)
    scene, az, base = _scene_and_draws(seed, w_idx, snr, p_idx, i, flies)
    start = datetime(2026, 3, 1, 9, 30, tzinfo=timezone.utc)
    dwells = [_lazy_dwell(scene, preset, base + j, bench_serial(claims), az, start, j, world, pre.dwell_s)
              for j in range(max_dwells)]
    out = decide_track(checker, dwells, None)
    prof = all_profiles()
    recs = [_dwell_record(s, prof[claims], prof[flies], pre.config.unambiguous_velocity_mps) for s in checker.seen]
    return TrackResult(world, float(snr), cat, flies, claims, why, out.decision, list(out.reasons), out.dwells_used,
                       max_dwells, round(out.llr, 4), round(time.perf_counter() - t0, 2), recs)


def _one_diag(job: tuple) -> list[dict[str, Any]]:
    """k single dwells of one genuine (or any) scene, each checked alone: the per-dwell diagnosis."""
    from authn.check import CheckInput
    from lab.bench.track import track_recordings

    preset, world, w_idx, snr, seed, p_idx, (cat, flies, claims, why), i, k = job
    checker = _checker()
    checker.seen.clear()
    pre = get_preset(preset)
    scene, az, base = _scene_and_draws(seed, w_idx, snr, p_idx, i, flies)
    recs = track_recordings(scene, preset, list(range(base, base + k)), bench_serial(claims), az,
                            spacing_s=pre.dwell_s, world=world)
    out = []
    prof = all_profiles()
    for rec in recs:
        checker.seen.clear()
        o = checker.decide_one(CheckInput.recording(rec, bench_serial(claims)))
        row = {"world": world, "snr_db": float(snr), "category": cat, "flies": flies, "claims": claims, "track": i,
               "decision": o.decision, "reasons": list(o.reasons)}
        if checker.seen:
            row.update(_dwell_record(checker.seen[-1], prof[claims], prof[flies], pre.config.unambiguous_velocity_mps))
        out.append(row)
    return out


def _jobs(preset: str, worlds: Iterable[str], snrs: Iterable[float], n: int, seed: int, extra: int,
          categories: Iterable[str]) -> list[tuple]:
    cats = set(categories)
    return [(preset, w, w_idx, float(snr), seed, p_idx, pr, i, extra)
            for w_idx, w in enumerate(worlds) for snr in snrs for p_idx, pr in enumerate(pairs()) if pr[0] in cats
            for i in range(n)]


def _run(fn: Any, jobs: list[tuple], workers: int) -> list[Any]:
    if workers <= 1:
        return [fn(j) for j in jobs]
    with ProcessPoolExecutor(workers) as ex:
        return list(ex.map(fn, jobs, chunksize=1))


def run_track_accuracy(preset: str = "paper", worlds: tuple[str, ...] = ("heldout",),
                       snrs: tuple[float, ...] = (10.0, 0.0), n: int = 16, seed: int = 7, workers: int = 1,
                       categories: tuple[str, ...] = CATEGORIES) -> list[TrackResult]:
    """n tracks per (flown, claimed) pair, world and SNR; each `TRACK_SECONDS` of back-to-back dwells."""
    max_dwells = int(TRACK_SECONDS / get_preset(preset).dwell_s)
    return _run(_one_track, _jobs(preset, worlds, snrs, n, seed, max_dwells, categories), workers)


def run_diagnosis(preset: str = "paper", worlds: tuple[str, ...] = ("heldout",), snrs: tuple[float, ...] = (10.0, 0.0),
                  n: int = 12, dwells: int = 8, seed: int = 7, workers: int = 1,
                  categories: tuple[str, ...] = ("genuine",)) -> list[dict[str, Any]]:
    """n scenes per pair x `dwells` single dwells each, every one checked alone (no early stop)."""
    rows = _run(_one_diag, _jobs(preset, worlds, snrs, n, seed, dwells, categories), workers)
    return [r for rs in rows for r in rs]


# --- tables ---------------------------------------------------------------------------------------

def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


#: Per world, the (flown, claimed) models whose 2 s tracks no rule separates at the targets' error rates,
#: measured by `lab.bench.reach` (docs/tracks.md, "What any per-dwell scoring can reach": fitted on 800 of
#: the held-out world's own dwells per airframe, M300 against M600 stays at 7.3 % EER at 10 dB and 16.5 % at
#: 0 dB over 75-dwell tracks). Their genuine and type-spoof tracks are reported apart as well as within
#: the rows.
OUT_OF_REACH: dict[str, frozenset[tuple[str, str]]] = {
    "heldout": frozenset({("m300", "m300"), ("m600", "m600"), ("m300", "m600"), ("m600", "m300")})}


def track_accuracy_table(results: list[TrackResult]) -> list[str]:
    """Per world, SNR and category (separable pairs only): right decisions against the target, median
    and mean dwells used; where `OUT_OF_REACH` names pairs of the row, the row again without them."""
    lines = ["| world | SNR dB | claims | pairs | tracks | right | target | inconclusive | median dwells "
             "| mean dwells |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    groups: dict[tuple, list[TrackResult]] = {}
    for r in results:
        if r.category == "genuine" or r.separable:
            groups.setdefault((r.world, -r.snr_db, CATEGORIES.index(r.category), 0), []).append(r)
            if (r.flies, r.claims) not in OUT_OF_REACH.get(r.world, ()):
                groups.setdefault((r.world, -r.snr_db, CATEGORIES.index(r.category), 1), []).append(r)
    for (world, nsnr, c_idx, reach_only), rs in sorted(groups.items()):
        whole = groups[(world, nsnr, c_idx, 0)]
        if reach_only and len(rs) == len(whole):
            continue
        cat = CATEGORIES[c_idx]
        want = "accept" if cat == "genuine" else "reject"
        right = sum(is_right(want, r.decision) for r in rs) / len(rs)
        target = TARGETS.get((cat, -nsnr))
        met = "" if target is None else (" **met**" if right >= target else " not met")
        used = [r.dwells_used for r in rs]
        label = cat.replace('_', ' ') + (" (pairs in reach)" if reach_only else "")
        lines.append(f"| {world} | {-nsnr:g} | {label} | {len({(r.flies, r.claims) for r in rs})} | "
                     f"{len(rs)} | {_pct(right)} | {'' if target is None else _pct(target)}{met} | "
                     f"{_pct(sum(r.decision == 'inconclusive' for r in rs) / len(rs))} | "
                     f"{statistics.median(used):g} | {statistics.fmean(used):.1f} |")
    return lines


def pair_table(results: list[TrackResult]) -> list[str]:
    lines = ["| world | SNR dB | flown -> claimed | separable by | tracks | right | median dwells | wrong: reasons |",
             "|---|---|---|---|---|---|---|---|"]
    groups: dict[tuple, list[TrackResult]] = {}
    for r in results:
        groups.setdefault((r.world, -r.snr_db, CATEGORIES.index(r.category), r.flies, r.claims), []).append(r)
    for (world, nsnr, c_idx, flies, claims), rs in sorted(groups.items()):
        want = "accept" if CATEGORIES[c_idx] == "genuine" else "reject"
        wrong: dict[str, int] = {}
        for r in rs:
            if not is_right(want, r.decision):
                key = ",".join(r.reasons) or r.decision
                wrong[key] = wrong.get(key, 0) + 1
        why = "(genuine)" if c_idx == 0 else (" + ".join(rs[0].separable) or "**not separable**")
        lines.append(f"| {world} | {-nsnr:g} | {flies} -> {claims} | {why} | {len(rs)} | "
                     f"{_pct(sum(is_right(want, r.decision) for r in rs) / len(rs))} | "
                     f"{statistics.median(r.dwells_used for r in rs):g} | "
                     f"{'; '.join(f'{k} {v}' for k, v in sorted(wrong.items()))} |")
    return lines


def _rate_right(r: dict[str, Any]) -> bool:
    """A diagnosis dwell's flash rate within `lab.accuracy.RATE_TOLERANCE` of its simulation's truth."""
    from lab.accuracy import RATE_TOLERANCE

    true = r["true_flash_rate_hz"]
    return bool(true) and abs(r["flash_rate_hz"] / true - 1) <= RATE_TOLERANCE


def _mean(xs: list[float]) -> str:
    return "n/a" if not xs else f"{statistics.fmean(xs):+.2f}"


def diagnosis_table(rows: list[dict[str, Any]]) -> list[str]:
    """Per world, SNR (and flown airframe): what the estimates and terms of genuine dwells were."""
    from signatures.classify.verify import RATE_BAND, ROTOR_BAND

    lines = ["| world | SNR dB | flown | dwells | accepted alone | physics ran | f in band of nominal "
             "| f half / double | f within 5 % of true | true f / nominal "
             "| rotors seen in band (median seen / R) | rate term mean "
             "(< 0) | rotors term mean (< 0) | classifier mean (< 0) | physics mean | LLR mean (< 0) | "
             "classifier said |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        for key in ((r["world"], -r["snr_db"], "all"), (r["world"], -r["snr_db"], r["flies"])):
            groups.setdefault(key, []).append(r)
    for (world, nsnr, flies), rs in sorted(groups.items(), key=lambda kv: (kv[0][0], kv[0][1], kv[0][2] != "all",
                                                                          kv[0][2])):
        det = [r for r in rs if "terms" in r]
        phys = [r for r in det if r["terms"]["rate"] is not None]
        ratio = [r["flash_rate_hz"] / r["nominal_flash_rate_hz"] for r in phys]
        inband = sum(RATE_BAND[0] <= x <= RATE_BAND[1] for x in ratio)
        slip = sum(0.4 <= x <= 0.6 for x in ratio), sum(1.6 <= x <= 2.4 for x in ratio)
        true_ok = [r for r in phys if _rate_right(r)]
        true_nom = [r["true_flash_rate_hz"] / r["flown_nominal_flash_rate_hz"] for r in det if r["true_flash_rate_hz"]]
        seen = [r["rotors_seen"] / r["claimed_rotors"] for r in det if r["rotors_seen"] > 0]
        rot_ok = sum(ROTOR_BAND[0] <= x <= ROTOR_BAND[1] for x in seen)

        def term(name: str, det: list[dict] = det) -> str:
            xs = [r["terms"][name] for r in det if r["terms"].get(name) is not None]
            return "n/a" if not xs else f"{_mean(xs)} ({100 * sum(x < 0 for x in xs) / len(xs):.0f} %)"

        llrs = [r["llr"] for r in det if r["llr"] is not None]
        labels: dict[str, int] = {}
        for r in det:
            lab = r["label"] if r["known"] else "unknown"
            labels[lab] = labels.get(lab, 0) + 1
        n = max(len(phys), 1)
        lines.append(
            f"| {world} | {-nsnr:g} | {flies} | {len(rs)} | "
            f"{_pct(sum(r['decision'] == 'accept' for r in rs) / len(rs))} | "
            f"{_pct(len(phys) / max(len(rs), 1))} | {_pct(inband / n)} | {_pct(slip[0] / n)} / {_pct(slip[1] / n)} | "
            f"{_pct(len(true_ok) / n)} | {statistics.median(true_nom) if true_nom else float('nan'):.2f} "
            f"({min(true_nom, default=float('nan')):.2f}-{max(true_nom, default=float('nan')):.2f}) | "
            f"{_pct(rot_ok / max(len(seen), 1))} ({statistics.median(seen) if seen else float('nan'):.2f}) | "
            f"{term('rate')} | {term('rotors')} | {term('classifier')} | "
            f"{_mean([r['terms']['physics'] for r in phys if r['terms']['physics'] is not None])} | "
            f"{_mean(llrs)} ({100 * sum(x < 0 for x in llrs) / max(len(llrs), 1):.0f} %) | "
            f"{', '.join(f'{k} {v}' for k, v in sorted(labels.items(), key=lambda kv: -kv[1])[:4])} |")
    return lines


#: Bounds of the `spread_table` columns: the flown rotors' pattern rates, (max - min) / mean.
SPREAD_BINS = (0.04, 0.08)


def spread_table(rows: list[dict[str, Any]]) -> list[str]:
    """Per world and SNR: the flash rate read within 5 % of the truth, by how far the flown rotors'
    own rates spread (`true_rate_spread`). The period search matches one period to within
    `signatures.dsp.flash_period.TOL_FRACTION` in `paper`; a rotor that turns a few per cent off the
    others flashes off that period."""
    lo, hi = SPREAD_BINS
    names = (f"< {100 * lo:g} %", f"{100 * lo:g}-{100 * hi:g} %", f">= {100 * hi:g} %")
    lines = ["| world | SNR dB | " + " | ".join(f"rotor rates spread {n}: dwells, f within 5 %" for n in names) + " |",
             "|---|---|---|---|---|"]
    groups: dict[tuple, list[list[bool]]] = {}
    for r in rows:
        if "terms" not in r or r.get("true_rate_spread") is None or not r["true_flash_rate_hz"]:
            continue
        col = 0 if r["true_rate_spread"] < lo else 1 if r["true_rate_spread"] < hi else 2
        ok = r["terms"]["rate"] is not None and _rate_right(r)
        groups.setdefault((r["world"], -r["snr_db"]), [[], [], []])[col].append(ok)
    for (world, nsnr), cols in sorted(groups.items()):
        cells = [f"{len(c)}, {_pct(sum(c) / len(c))}" if c else "0, n/a" for c in cols]
        lines.append(f"| {world} | {-nsnr:g} | " + " | ".join(cells) + " |")
    return lines


class Variant(NamedTuple):
    """A what-if variant, evaluated offline on the diagnosis dwells: constants of `signatures.classify.verify`
    to override, the classifier clip (None: the classifier term dropped), the rotors term kept, the
    track correlation rho, and the flash rate read right (the simulation's true blade-flash rate in
    place of the estimate: an oracle that bounds what a better rate estimator alone could give)."""

    name: str
    consts: dict[str, Any]
    clip: float | None
    rotors: bool
    rho: float
    true_rate: bool = False

    def walk(self, dwells: list[dict[str, Any]]) -> tuple[list[tuple[float, bool]], str]:
        """One scene's dwells scored under the variant, and how the sequential test ends on them."""
        vals = [_variant_llr(r, self.consts, self.clip, self.rotors, self.true_rate) for r in dwells]
        return vals, _walk(vals, self.rho)[0]


WHAT_IF: tuple[Variant, ...] = (
    Variant("shipped", {}, 3.0, True, 0.2),
    Variant("classifier clip 1", {}, 1.0, True, 0.2),
    Variant("no classifier term", {}, None, True, 0.2),
    Variant("no rotors term", {}, 3.0, False, 0.2),
    Variant("ROTOR_BAND 0.45-1.10", {"ROTOR_BAND": (0.45, 1.10)}, 3.0, True, 0.2),
    Variant("REL_FLOOR 0.06", {"REL_FLOOR": 0.06}, 3.0, True, 0.2),
    Variant("rho 0.1", {}, 3.0, True, 0.1),
    Variant("rho 0.1, classifier clip 1", {}, 1.0, True, 0.1),
    Variant("rho 0.1, clip 1, ROTOR_BAND 0.45, REL_FLOOR 0.06", {"ROTOR_BAND": (0.45, 1.10), "REL_FLOOR": 0.06}, 1.0,
            True, 0.1),
    Variant("rho 0.05", {}, 3.0, True, 0.05),
    Variant("flash rate read right (oracle)", {}, 3.0, True, 0.2, True),
    Variant("flash rate read right, no classifier term", {}, None, True, 0.2, True),
)


def _variant_llr(r: dict[str, Any], consts: dict[str, Any], clip: float | None, rotors: bool,
                 true_rate: bool = False) -> tuple[float, bool]:
    """A diagnosis dwell's LLR under a variant: (LLR, physics term present). The physics term is
    recomputed from the stored estimates (tips aliased in `paper`: no blade term); the classifier
    term re-clipped (clipping is monotone, so the stored, clipped term can be clipped further).
    `true_rate`: the flash rate is the flown airframe's true blade-flash rate (twice its mean rotor
    rate), read in every dwell that ran the radar at the estimate's relative std (3 % where none)."""
    from signatures.classify import verify as V

    saved = {k: getattr(V, k) for k in consts}
    try:
        for k, v in consts.items():
            setattr(V, k, v)
        f = {"flash_rate_hz": r["flash_rate_hz"], "flash_rate_std_hz": r["flash_rate_std_hz"],
             "flash_score": r["flash_score"], "tip_aliased": r["tip_aliased"], "tip_speed_mps": 0.0,
             "rotors_seen": r["rotors_seen"] if rotors else 0.0, "rotors_seen_std": r["rotors_seen_std"]}
        if true_rate and r.get("true_rotor_rate_hz"):
            rel = r["flash_rate_std_hz"] / r["flash_rate_hz"] if r["flash_rate_hz"] > 0 else 0.03
            f.update(flash_rate_hz=2.0 * r["true_rotor_rate_hz"], flash_score=max(r["flash_score"], V.MIN_FLASH_SCORE))
            f["flash_rate_std_hz"] = rel * f["flash_rate_hz"]
        claimed = all_profiles()[r["claims"]]
        if hasattr(V, "Bands"):  # per-model bands (site enrolment): the bands go in as an argument
            bands = V.Bands(rate=consts.get("RATE_BAND", V.RATE_BAND), rotors=consts.get("ROTOR_BAND", V.ROTOR_BAND))
            phys = V._physics(f, claimed, None, bands)
        else:
            phys = V._physics(f, claimed, None)
    finally:
        for k, v in saved.items():
            setattr(V, k, v)
    llr = 0.0 if phys is None else phys[0]
    k = r["terms"].get("classifier")
    if clip is not None and k is not None:
        llr += max(-clip, min(clip, k))
    return llr, phys is not None


def _walk(dwells: list[tuple[float, bool]], rho: float = 0.2) -> tuple[str, int]:
    """`authn.track`'s sequential test alone (default bounds, discount and cap), as the default
    policy's track rules decide it: (accept | reject | inconclusive, dwells used)."""
    from authn.sprt import Sprt

    sprt = Sprt(correlation=rho)
    acc, rej = math.ceil(sprt.accept_nats * 100), math.floor(sprt.reject_nats * 100)
    inc: list[float] = []
    for llr, phys in dwells:
        inc.append(sprt.increment(llr, phys))
        cn = round(sprt.track_llr(inc) * 100)
        if cn >= acc:
            return "accept", len(inc)
        if cn <= rej:
            return "reject", len(inc)
    return "inconclusive", len(inc)


def what_if_table(rows: list[dict[str, Any]]) -> list[str]:
    """Per world, SNR and variant: genuine / type-spoof / unseen dwells on the right side of 0, and
    the diagnosis scenes' dwells walked as tracks (truncated at the scene's dwells: inconclusive
    tracks are rejected, as `track-inconclusive`). Only rows whose radar ran are used."""
    lines = ["| world | SNR dB | variant | genuine dwells > 0 | spoof dwells < 0 | unseen dwells < 0 | genuine tracks "
             "accepted | spoof tracks rejected (inconclusive) | unseen tracks rejected (inconclusive) |",
             "|---|---|---|---|---|---|---|---|---|"]
    keyed: dict[tuple, dict[tuple, list[dict]]] = {}
    for r in rows:
        if "terms" in r:
            keyed.setdefault((r["world"], -r["snr_db"]), {}).setdefault(
                (r["category"], r["flies"], r["claims"], r["track"]), []).append(r)
    for (world, nsnr), scenes in sorted(keyed.items()):
        for variant in WHAT_IF:
            cells = []
            walks: dict[str, list[str]] = {c: [] for c in CATEGORIES}
            dw: dict[str, list[float]] = {c: [] for c in CATEGORIES}
            for (cat, *_), rs in scenes.items():
                vals, end = variant.walk(rs)
                dw[cat] += [v for v, _ in vals]
                walks[cat].append(end)
            for cat in CATEGORIES:
                xs = dw[cat]
                ok = sum((x > 0) if cat == "genuine" else (x < 0) for x in xs)
                cells.append("n/a" if not xs else _pct(ok / len(xs)))
            for cat in CATEGORIES:
                ws = walks[cat]
                if not ws:
                    cells.append("n/a")
                elif cat == "genuine":
                    cells.append(_pct(ws.count("accept") / len(ws)))
                else:
                    cells.append(f"{_pct((len(ws) - ws.count('accept')) / len(ws))} "
                                 f"({_pct(ws.count('inconclusive') / len(ws))})")
            lines.append(f"| {world} | {-nsnr:g} | {variant.name} | " + " | ".join(cells) + " |")
    return lines


#: The variants `what_if_pair_table` breaks down per pair.
PAIR_VARIANTS = ("shipped", "no classifier term", "flash rate read right (oracle)",
                 "flash rate read right, no classifier term")


def what_if_pair_table(rows: list[dict[str, Any]], names: tuple[str, ...] = PAIR_VARIANTS) -> list[str]:
    """Per world, SNR and (category, flown, claimed) pair: the scenes walked as tracks under each of
    `names` (WHAT_IF variants), as right tracks of all (accepted genuine, not accepted impostors)."""
    variants = [v for v in WHAT_IF if v.name in names]
    lines = ["| world | SNR dB | flown -> claimed | " + " | ".join(v.name for v in variants) + " |",
             "|---|---|---|" + "---|" * len(variants)]
    keyed: dict[tuple, dict[int, list[dict]]] = {}
    for r in rows:
        if "terms" in r:
            key = (r["world"], -r["snr_db"], CATEGORIES.index(r["category"]), r["flies"], r["claims"])
            keyed.setdefault(key, {}).setdefault(r["track"], []).append(r)
    for (world, nsnr, c_idx, flies, claims), scenes in sorted(keyed.items()):
        cells = []
        for variant in variants:
            ends = [variant.walk(rs)[1] for rs in scenes.values()]
            right = ends.count("accept") if c_idx == 0 else len(ends) - ends.count("accept")
            cells.append(f"{right}/{len(ends)}")
        lines.append(f"| {world} | {-nsnr:g} | {flies} -> {claims} | " + " | ".join(cells) + " |")
    return lines


#: The terms a dwell's verification LLR is the sum of (`signatures.classify.verify`), and their sum.
TERMS = ("physics", "classifier", "total")


def _capped_term(r: dict[str, Any], which: str, cap: float) -> float | None:
    """A diagnosis dwell's term capped at +-cap as the track test caps the LLR (None: it abstained;
    "total": the capped LLR of a dwell that verified anything, as `lab.bench.track.dependence`)."""
    t = r.get("terms") or {}
    p, k = t.get("physics"), t.get("classifier")
    x = (None if p is None and k is None else (p or 0.0) + (k or 0.0)) if which == "total" else t.get(which)
    return None if x is None else max(-cap, min(cap, float(x)))


def _term_values(rs: list[dict[str, Any]], which: str, cap: float) -> list[float]:
    """One scene's capped values of a term, abstained dwells left out."""
    return [v for v in (_capped_term(r, which, cap) for r in rs) if v is not None]


def _pair_icc(scenes: list[list[dict[str, Any]]], which: str, cap: float) -> tuple[float, int]:
    """(ICC of one pair's scenes, dwells): `lab.bench.track.icc` over the scenes' capped term values
    (abstained dwells left out; no spread at all: 0, as `dependence` counts it); NaN with fewer than
    two scenes of two values."""
    from lab.bench.track import icc

    groups = [g for g in (_term_values(rs, which, cap) for rs in scenes) if len(g) >= 2]
    if len(groups) < 2:
        return float("nan"), 0
    return icc(groups), sum(len(g) for g in groups)


def term_icc(pairs_scenes: dict[tuple[str, str], list[list[dict[str, Any]]]], which: str, cap: float,
             rng: np.random.Generator | None = None) -> float:
    """The discount's statistic per term (`lab.bench.track.dependence`'s): the ICC within each
    (flown, claimed) pair, weighted by the pair's dwells. With `rng`: one bootstrap replicate
    (the scenes of each pair resampled with replacement)."""
    num = den = 0.0
    for scenes in pairs_scenes.values():
        if rng is not None:
            scenes = [scenes[i] for i in rng.integers(len(scenes), size=len(scenes))]
        v, w = _pair_icc(scenes, which, cap)
        if w:
            num, den = num + w * v, den + w
    return num / den if den else float("nan")


def _scene_mean_corr(pairs_scenes: dict[tuple[str, str], list[list[dict[str, Any]]]], cap: float) -> float:
    """Pearson correlation of the scenes' mean physics and mean classifier terms, each pair's own
    means removed: > 0 when a scene that is bad for one term is bad for the other (a shared bias)."""
    xs: list[float] = []
    ys: list[float] = []
    for scenes in pairs_scenes.values():
        means = []
        for rs in scenes:
            p, k = _term_values(rs, "physics", cap), _term_values(rs, "classifier", cap)
            if p and k:
                means.append((statistics.fmean(p), statistics.fmean(k)))
        if len(means) >= 2:
            a = np.asarray(means) - np.mean(means, axis=0)
            xs += list(a[:, 0])
            ys += list(a[:, 1])
    if len(xs) < 3 or np.std(xs) == 0 or np.std(ys) == 0:
        return float("nan")
    return float(np.corrcoef(xs, ys)[0, 1])


def _diag_scenes(rows: list[dict[str, Any]], first: int | None = None) -> dict[tuple, dict[tuple, list[list[dict]]]]:
    """(world, SNR, category) -> (flown, claimed) -> each scene's dwells in order (the first `first`)."""
    keyed: dict[tuple, dict[tuple, dict[int, list[dict]]]] = {}
    for r in rows:
        keyed.setdefault((r["world"], r["snr_db"], r["category"]), {}).setdefault(
            (r["flies"], r["claims"]), {}).setdefault(r["track"], []).append(r)
    return {k: {p: [rs[:first] if first else rs for _, rs in sorted(sc.items())] for p, sc in v.items()}
            for k, v in keyed.items()}


def term_icc_table(rows: list[dict[str, Any]], first: int | None = None, boot: int = 200) -> list[str]:
    """Per world, SNR and category of a `--diagnose --json` file: the ICC within a pair of the
    capped physics term, classifier term and their sum (90 % interval of `boot` scene bootstraps),
    the terms' mean (sd), how often the physics abstained, and the scene-mean correlation of the
    two terms (`_scene_mean_corr`)."""
    from authn.track import DWELL_CAP_NATS as cap

    lines = ["| world | SNR dB | claims | pairs x scenes x dwells | ICC physics | ICC classifier | ICC total "
             "| physics mean (sd) | classifier mean (sd) | physics abstained | scene means phys ~ clf |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for (world, snr, cat), ps in sorted(_diag_scenes(rows, first).items(),
                                        key=lambda kv: (kv[0][0], -kv[0][1], CATEGORIES.index(kv[0][2]))):
        cells = []
        for which in TERMS:
            rng = np.random.default_rng([31, len(cells)])
            reps = [x for x in (term_icc(ps, which, cap, rng) for _ in range(boot)) if not math.isnan(x)]
            lo, hi = np.percentile(reps, [5, 95]) if reps else (float("nan"), float("nan"))
            cells.append(f"{term_icc(ps, which, cap):.2f} [{lo:.2f}, {hi:.2f}]")
        dw = [r for scenes in ps.values() for rs in scenes for r in rs]
        det = [r for r in dw if r.get("terms")]
        vals = {w: _term_values(det, w, cap) for w in ("physics", "classifier")}
        n_sc = sum(len(s) for s in ps.values())
        stats = [f"{statistics.fmean(v):+.2f} ({statistics.pstdev(v):.2f})" if v else "n/a" for v in vals.values()]
        lines.append(f"| {world} | {snr:g} | {cat.replace('_', ' ')} | {len(ps)} x {n_sc // len(ps)} x "
                     f"{len(dw) // max(n_sc, 1)} | {' | '.join(cells)} | {' | '.join(stats)} | "
                     f"{_pct(sum(r['terms'].get('physics') is None for r in det) / max(len(det), 1))} | "
                     f"{_scene_mean_corr(ps, cap):+.2f} |")
    return lines


def term_increments(rs: list[dict[str, Any]], cap: float) -> list[tuple[float, float]]:
    """Diagnosis dwells as (physics, classifier) increments of a per-term test: the dwell's LLR capped
    at +-cap with both terms scaled alike (so their sum is `Sprt.increment`'s); physics abstained:
    only a negative classifier part. Dwells that verified nothing are left out (not counted in n)."""
    out = []
    for r in rs:
        t = r.get("terms") or {}
        p, k = t.get("physics"), t.get("classifier")
        if p is None and k is None:
            continue
        if p is None:
            out.append((0.0, min(0.0, max(-cap, float(k)))))
            continue
        s = float(p) + float(k or 0.0)
        f = 1.0 if abs(s) <= cap else cap / abs(s)
        out.append((float(p) * f, float(k or 0.0) * f))
    return out


def walk_terms(incs: list[tuple[float, float]], rho_physics: float, rho_classifier: float) -> tuple[str, int]:
    """A per-term discount, sum_phys / (1 + (n-1) rho_phys) + sum_clf / (1 + (n-1) rho_clf), at the
    default bounds as `_walk` decides them: (accept | reject | inconclusive, dwells used); n counts
    the dwells that move a sum, as `authn.sprt.observations` does."""
    from authn.sprt import Sprt

    sprt = Sprt()
    acc, rej = math.ceil(sprt.accept_nats * 100), math.floor(sprt.reject_nats * 100)
    sp = sk = 0.0
    seen = 0
    for n, (p, k) in enumerate(incs, 1):
        sp, sk, seen = sp + p, sk + k, seen + (p != 0.0 or k != 0.0)
        m = max(seen, 1)
        cn = round((sp / (1 + (m - 1) * rho_physics) + sk / (1 + (m - 1) * rho_classifier)) * 100)
        if cn >= acc:
            return "accept", n
        if cn <= rej:
            return "reject", n
    return "inconclusive", len(incs)


def term_walk_table(rows: list[dict[str, Any]], rhos: list[tuple[float, float]]) -> list[str]:
    """The diagnosis scenes walked as tracks (all their dwells; inconclusive is rejected, as
    `track-inconclusive`: right for an impostor) under today's single rho and under per-term rhos
    (rho_physics, rho_classifier)."""
    from authn.track import DWELL_CAP_NATS as cap, DWELL_CORRELATION as rho

    lines = ["| world | SNR dB | claims | tracks | rho physics / classifier | right | inconclusive | median dwells |",
             "|---|---|---|---|---|---|---|---|"]
    for (world, snr, cat), ps in sorted(_diag_scenes(rows).items(),
                                        key=lambda kv: (kv[0][0], -kv[0][1], CATEGORIES.index(kv[0][2]))):
        want = "accept" if cat == "genuine" else "reject"
        tracks = [term_increments(rs, cap) for scenes in ps.values() for rs in scenes]
        for rp, rk in [(rho, rho), *rhos]:
            res = [walk_terms(t, rp, rk) for t in tracks]
            label = f"{rp:g} / {rk:g}" + (" (today)" if (rp, rk) == (rho, rho) else "")
            lines.append(f"| {world} | {snr:g} | {cat.replace('_', ' ')} | {len(res)} | {label} | "
                         f"{_pct(sum((d == 'accept') == (want == 'accept') for d, _ in res) / len(res))} | "
                         f"{_pct(sum(d == 'inconclusive' for d, _ in res) / len(res))} | "
                         f"{statistics.median(n for _, n in res):g} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lab.bench.track_accuracy", description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--world", action="append", choices=("heldout", "training"))
    ap.add_argument("--snr", action="append", type=float)
    ap.add_argument("--n", type=int, default=16, help="tracks (or diagnosis scenes) per pair, world and SNR")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--category", action="append", choices=CATEGORIES)
    ap.add_argument("--diagnose", action="store_true", help="per-dwell diagnosis of single dwells instead of tracks")
    ap.add_argument("--dwells", type=int, default=8, help="dwells per diagnosis scene")
    ap.add_argument("--json", help="write every track / dwell to this file")
    ap.add_argument("--what-if", metavar="DIAG_JSON", help="print the what-if table of a --diagnose --json file")
    ap.add_argument("--icc", metavar="DIAG_JSON", help="print the ICC within a pair per verification term of a "
                    "--diagnose --json file")
    ap.add_argument("--first", type=int, help="--icc: the first FIRST dwells of each scene only")
    ap.add_argument("--rho-terms", action="append", metavar="PHYS,CLF", default=[],
                    help="--icc: also walk the scenes as tracks under per-term correlations (repeatable)")
    a = ap.parse_args(argv)
    worlds, snrs = tuple(a.world or ("heldout",)), tuple(a.snr or (10.0, 0.0))
    if a.what_if:
        with open(a.what_if) as fh:
            rows = json.load(fh)
        print("\n".join(what_if_table(rows)))
        print()
        print("\n".join(what_if_pair_table(rows)))
        return 0
    if a.icc:
        with open(a.icc) as fh:
            rows = json.load(fh)
        print("\n".join(term_icc_table(rows, a.first)))
        if a.rho_terms:
            rhos = [(float(x), float(y)) for x, y in (s.split(",") for s in a.rho_terms)]
            print()
            print("\n".join(term_walk_table(rows, rhos)))
        return 0
    t0 = time.perf_counter()
    print(f"# {' '.join(['python -m lab.bench.track_accuracy', *(argv if argv is not None else sys.argv[1:])])}")
    print(f"# {datetime.now(timezone.utc).date()}, {os.cpu_count()} cores")
    if a.diagnose:
        rows = run_diagnosis(a.preset, worlds, snrs, a.n, a.dwells, a.seed, a.workers,
                             tuple(a.category or ("genuine",)))
        print("\n".join(diagnosis_table(rows)))
        print()
        print("\n".join(spread_table(rows)))
        if a.json:
            with open(a.json, "w") as fh:
                json.dump(rows, fh)
    else:
        print("separable pairs (rule: nominal flash rates outside each other's RATE_BAND, or rotors differ by >= 2):")
        for cat, flies, claims, why in pairs():
            if cat != "genuine":
                print(f"#   {flies} -> {claims}: {' + '.join(why) or 'NOT separable'}")
        res = run_track_accuracy(a.preset, worlds, snrs, a.n, a.seed, a.workers, tuple(a.category or CATEGORIES))
        print("\n".join(track_accuracy_table(res)))
        print()
        print("\n".join(pair_table(res)))
        if a.json:
            with open(a.json, "w") as fh:
                json.dump([asdict(r) for r in res], fh)
    print(f"# {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
