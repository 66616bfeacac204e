"""Single dwells under the one decision rule: what one `authn check FILE` decides for every ordered pair of
shipped profiles, and how far apart one dwell puts each pair (the separation the shipped cards state).

Each dwell is a scene of `lab.bench.decisions.CLAIM_SCENES` at one SNR, flown by a shipped airframe (or an
unseen one), rendered in a world (`training`, `randomised`: the training simulator with each scene's
nuisances drawn, or `heldout`: `lab.heldout`'s signal model), and checked by the real `Checker` against the
bench registry (every shipped model registered) once per claimed shipped model. Reported per (world, SNR,
flown, claimed): accepted / rejected / inconclusive. Per (claimed, alternative): the mean per-dwell
increment of a genuine claim against the alternative and of the alternative flying the claim, and the
dwells the sequential test needs at the default error rates (`authn.sprt.Sprt.dwells_to_decide`).

    python -m lab.bench.single_dwell --world randomised --world heldout --snr 10 --snr 0 --n 40 --workers 2
    python -m lab.bench.single_dwell --world randomised --snr 10 --snr 0 --n 60 --write-card paper

`--write-card PRESET` writes the separation measured on the first world into the shipped bundle's card
(`separation`, docs/classifiers.md): what `authn check` reads to say how many dwells would decide a claim
and which shipped pairs no track decides (`radar-confusable-unsigned` without a site card).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from signatures.classify.verify import UNKNOWN

#: A pair no 2 s track of back-to-back `paper` dwells decides (`lab.bench.reach.TRACK_DWELLS`) is one radar
#: cannot separate: a claim of it needs a signature.
DECIDING_DWELLS = 75


@dataclass(frozen=True)
class DwellClaim:
    world: str
    snr_db: float
    flies: str
    claims: str
    decision: str
    reasons: tuple[str, ...]
    physics: bool
    against: dict[str, float] | None  # capped increments per alternative (None: nothing verified)
    raw: dict[str, float] | None = None  # the verification's LLR per alternative, uncapped


def _job(job: tuple) -> list[DwellClaim]:
    from authn.check import Checker
    from authn.scenario import Broadcast, remote_id_rows, simulate_flight
    from authn.sprt import Sprt
    from lab.bench.decisions import CLAIM_SCENES, bench_serial, register_identities
    from lab.heldout import unseen_profiles
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.sim.sampling import randomised, sample_scene

    world, snr, preset, n, seed, w_idx, s_idx, targets = job
    shipped = list(shipped_profiles())
    profiles = {**shipped_profiles(), **unseen_profiles()}
    flown = shipped + ["unseen"]
    unseen = list(unseen_profiles())
    pre = get_preset(preset)
    out: list[DwellClaim] = []
    now = datetime.now(timezone.utc)
    with tempfile.TemporaryDirectory() as tmp:
        db = f"sqlite:///{Path(tmp) / 'single.sqlite3'}"
        register_identities(db)
        checker = Checker(db, sprt=Sprt(*targets))
        for f_idx, kind in enumerate(flown):
            rng = np.random.default_rng([seed, s_idx, f_idx, 29])  # the same scenes in every world
            for i in range(n):
                flies = unseen[i % len(unseen)] if kind == "unseen" else kind
                scene = sample_scene(rng, profiles[flies], replace(CLAIM_SCENES, snr_db=(float(snr), float(snr))))
                az, sim_seed = float(rng.uniform(0.0, 360.0)), int(rng.integers(2**31))
                for claims in shipped:
                    bc = Broadcast(serial=bench_serial(claims))
                    if world == "heldout":
                        from lab import heldout

                        rec, _ = heldout.simulate(scene, pre, sim_seed, start_time=now)
                        rows, times = remote_id_rows(rec, scene, bc, az, pre.dwell_s)
                        rec = replace(rec, remote_id=rows, remote_id_time_s=times)
                    else:
                        # the same nuisances for every claim of the scene
                        nuisance = np.random.default_rng([sim_seed, 41])
                        sc = randomised(scene, nuisance) if world == "randomised" else scene
                        rec = simulate_flight(sc, pre, sim_seed, bc, azimuth_deg=az, start_time=now)[0]
                    o = checker.evaluate_recording(rec)
                    incs = o.evidence.increments()
                    v = o.radar.verification if o.radar is not None else None
                    out.append(DwellClaim(world, float(snr), flies if kind != "unseen" else "unseen", claims,
                                          o.decision, tuple(o.reasons), bool(v is not None and "physics" in v.terms),
                                          incs[0] if incs else None,
                                          dict(v.against) if v is not None and v.terms else None))
    return out


def run(worlds: list[str], snrs: list[float], n: int, seed: int, workers: int, preset: str = "paper",
        targets: tuple[float, float] = (1e-3, 1e-2)) -> list[DwellClaim]:
    """n dwells per flown airframe, world and SNR, each claimed as every shipped model, decided at the
    error `targets` (false accept, false reject)."""
    jobs = [(w, s, preset, n, seed, wi, si, targets) for wi, w in enumerate(worlds) for si, s in enumerate(snrs)]
    if workers <= 1:
        return [r for j in jobs for r in _job(j)]
    with ProcessPoolExecutor(workers) as ex:
        return [r for rs in ex.map(_job, jobs) for r in rs]


def shares(rows: list[DwellClaim]) -> list[dict]:
    """Per (world, SNR, flown, claimed): the share accepted, rejected and inconclusive."""
    groups: dict[tuple, list[DwellClaim]] = defaultdict(list)
    for r in rows:
        groups[(r.world, r.snr_db, r.flies, r.claims)].append(r)
    out = []
    for (world, snr, flies, claims), rs in sorted(groups.items()):
        n = len(rs)
        out.append({"world": world, "snr_db": snr, "flies": flies, "claims": claims, "n": n,
                    "accepted": sum(r.decision == "accept" for r in rs) / n,
                    "rejected": sum(r.decision == "reject" for r in rs) / n,
                    "inconclusive": sum(r.decision == "inconclusive" for r in rs) / n,
                    "reasons": dict(sorted(_count(x for r in rs for x in r.reasons).items()))})
    return out


def _count(items) -> dict[str, int]:
    c: dict[str, int] = defaultdict(int)
    for x in items:
        c[x] += 1
    return c


def separation(rows: list[DwellClaim]) -> list[dict]:
    """Per world, SNR, claimed model and alternative: the mean per-dwell increment against the alternative
    of genuine claims, and the mean per-dwell increment (the least over alternatives) of the alternative
    flying the claim; the dwells each needs to decide at the default error rates."""
    from authn.sprt import Sprt

    sprt = Sprt()
    out = []
    keys = sorted({(r.world, r.snr_db, r.claims) for r in rows})
    for world, snr, claims in keys:
        genuine = [r.against for r in rows if (r.world, r.snr_db, r.flies, r.claims) == (world, snr, claims, claims)]
        alts = sorted({k for g in genuine if g for k in g})
        for alt in alts:
            g = [d.get(alt, min(d.values())) if d else 0.0 for d in genuine]
            flown = "unseen" if alt == UNKNOWN else alt  # the background's impostors: airframes never trained on
            imp = [min(r.against.values()) if r.against else 0.0 for r in rows
                   if (r.world, r.snr_db, r.claims, r.flies) == (world, snr, claims, flown)]
            mu_g = statistics.fmean(g) if g else float("nan")
            mu_i = statistics.fmean(imp) if imp else None
            out.append({"world": world, "snr_db": snr, "claimed": claims, "against": alt,
                        "genuine_nats": round(mu_g, 3),
                        "genuine_sd": round(statistics.pstdev(g), 3) if g else None, "n_genuine": len(g),
                        "impostor_nats": None if mu_i is None else round(mu_i, 3), "n_impostor": len(imp),
                        "dwells_to_accept": sprt.dwells_to_decide(mu_g) if mu_g > 0 else None,
                        "dwells_to_reject": None if mu_i is None or mu_i >= 0 else sprt.dwells_to_decide(mu_i)})
    return out


def combinations(rows: list[DwellClaim]) -> list[dict]:
    """The per-dwell score of two ways to combine the alternatives, by world and SNR: the minimum (what
    ships) and a uniform-prior mixture, -log mean_a exp(-LLR_a); beside the background alone (the score
    before the alternatives counted). Each as the equal error rate of genuine
    claims against type spoofs, against the M300 <-> M600 spoofs alone, and against unseen airframes."""
    from lab.bench.verification import eer

    def mixture(d: dict[str, float]) -> float:
        top = min(d.values())
        return top - float(np.log(np.mean([np.exp(-(x - top)) for x in d.values()])))

    out = []
    for world, snr in sorted({(r.world, r.snr_db) for r in rows}):
        rs = [r for r in rows if (r.world, r.snr_db) == (world, snr) and r.raw]
        for name, score in (("background only", lambda d: d[UNKNOWN]), ("minimum", lambda d: min(d.values())),
                            ("mixture", mixture)):
            g = [score(r.raw) for r in rs if r.flies == r.claims]
            row = {"world": world, "snr_db": snr, "combination": name}
            for label, pick in (("type_spoof", lambda r: r.flies not in (r.claims, "unseen")),
                                ("m300_m600", lambda r: {r.flies, r.claims} == {"m300", "m600"}),
                                ("unseen", lambda r: r.flies == "unseen")):
                row[f"eer_{label}"] = round(eer(g, [score(r.raw) for r in rs if pick(r)]), 4)
            out.append(row)
    return out


def card_section(sep: list[dict], world: str, command: str) -> dict:
    """The card's `separation`: per claimed model and alternative, the worst SNR's figures; `confusable`
    where no 2 s track decides the genuine claim or the alternative flying it (`DECIDING_DWELLS`), for a
    registered alternative (the background is reported, never confusable by name)."""
    pairs: dict[tuple[str, str], dict] = {}
    for s in sorted((s for s in sep if s["world"] == world), key=lambda s: s["genuine_nats"]):
        key = (s["claimed"], s["against"])
        p = pairs.setdefault(key, dict(s))  # the SNR where the genuine claim gains least
        if s["impostor_nats"] is not None and (p["impostor_nats"] is None or s["impostor_nats"] > p["impostor_nats"]):
            p["impostor_nats"] = s["impostor_nats"]  # the SNR where the impostor loses least
            p["dwells_to_reject"] = s["dwells_to_reject"]
    rows = []
    for (claimed, against), s in sorted(pairs.items()):
        slow = [s["dwells_to_accept"]] + ([s["dwells_to_reject"]] if s["n_impostor"] else [])
        rows.append({"claimed": claimed, "against": against, "genuine_nats_per_dwell": s["genuine_nats"],
                     "impostor_nats_per_dwell": s["impostor_nats"], "dwells_to_accept": s["dwells_to_accept"],
                     "dwells_to_reject": s["dwells_to_reject"],
                     # the background is not a model a claim could be confused with by name
                     "confusable": against != UNKNOWN and any(d is None or d > DECIDING_DWELLS for d in slow)})
    return {"world": world, "snr_db": sorted({s["snr_db"] for s in sep if s["world"] == world}),
            "deciding_dwells": DECIDING_DWELLS, "command": command, "pairs": rows}


def write_card(preset: str, section: dict) -> Path:
    """Write `section` as the shipped `preset` bundle card's `separation` (the card's digest changes; its
    files' digests do not)."""
    import signatures.models as models
    from signatures.classify.modelcard import card_bytes

    path = Path(models.__file__).parent / preset / "card.json"
    card = json.loads(path.read_text())
    card["separation"] = section
    path.write_bytes(card_bytes(card))
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lab.bench.single_dwell", description=__doc__.split("\n\n")[0])
    ap.add_argument("--world", action="append", choices=("training", "randomised", "heldout"))
    ap.add_argument("--snr", action="append", type=float)
    ap.add_argument("--n", type=int, default=40, help="dwells per flown airframe, world and SNR")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--false-accept", type=float, default=1e-3)
    ap.add_argument("--false-reject", type=float, default=1e-2)
    ap.add_argument("--json", type=Path, help="write every row and summary here")
    ap.add_argument("--write-card", metavar="PRESET", help="write the first world's separation into this shipped card")
    a = ap.parse_args(argv)
    worlds, snrs = a.world or ["randomised"], a.snr or [10.0, 0.0]
    rows = run(worlds, snrs, a.n, a.seed, a.workers, a.preset, (a.false_accept, a.false_reject))
    sh, sep = shares(rows), separation(rows)
    print("| world | SNR | flies | claims | n | accepted | rejected | inconclusive |")
    print("|---|---|---|---|---|---|---|---|")
    for s in sh:
        print(f"| {s['world']} | {s['snr_db']:g} | {s['flies']} | {s['claims']} | {s['n']} | {s['accepted']:.1%} | "
              f"{s['rejected']:.1%} | {s['inconclusive']:.1%} |")
    print("\n| world | SNR | claimed | against | genuine nats/dwell | impostor nats/dwell | dwells to accept | "
          "dwells to reject |")
    print("|---|---|---|---|---|---|---|---|")
    for s in sep:
        print(f"| {s['world']} | {s['snr_db']:g} | {s['claimed']} | {s['against']} | {s['genuine_nats']:+.2f} | "
              + ("" if s["impostor_nats"] is None else f"{s['impostor_nats']:+.2f}")
              + f" | {s['dwells_to_accept']} | {s['dwells_to_reject']} |")
    comb = combinations(rows)
    print("\n| world | SNR | combination | EER genuine / type spoofs | M300 <-> M600 | unseen |")
    print("|---|---|---|---|---|---|")
    for c in comb:
        print(f"| {c['world']} | {c['snr_db']:g} | {c['combination']} | {c['eer_type_spoof']:.1%} | "
              f"{c['eer_m300_m600']:.1%} | {c['eer_unseen']:.1%} |")
    if a.json:
        a.json.write_text(json.dumps({"rows": [asdict(r) for r in rows], "shares": sh, "separation": sep,
                                      "combinations": comb}, indent=1))
    if a.write_card:
        args = sys.argv[1:] if argv is None else argv
        kept = [x for i, x in enumerate(args) if x != "--json" and (i == 0 or args[i - 1] != "--json")]
        command = "python -m lab.bench.single_dwell " + " ".join(kept)
        print(f"wrote {write_card(a.write_card, card_section(sep, worlds[0], command))}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
