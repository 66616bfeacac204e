"""A site with one airframe on a CW radar, end to end (docs/enrolment.md "One airframe").

The site's radar is the S-band CW radar of `lab.accuracy.CONDITIONS` (3.30 / 3.35 / 3.40 GHz
carriers, 4096-pulse dwells), its one airframe the DJI-class quad (`DJI_QUAD`) hovering with its
rotors on or idling, tagged blades, strong clutter. Scene k of the site alternates in pairs between
`cw-hover-tagged` and `cw-idle-tagged`, so even and odd scenes hold both. Even scenes are the
enrolment recordings (one dwell each, labelled as the drone), odd scenes unseen tracks of
`--dwells` dwells each (the scene rendered with successive simulator seeds), every dwell carrying
the Remote ID of the serial claimed. The site registers the drone and an M300, an M600 and a
Phantom 4 (`SERIALS`) and runs the CW site policy (`lab.bench.cw_claims.cw_site_policy`); each
unseen track is checked by the real `Checker` (`authn check --track`) as genuine and as a type
spoof of each other registered model, and its first dwell alone as a single check.

    python -m lab.one_airframe --world training --enrol 20 --tracks 20 --dwells 8

Nothing here is tuned on; it measures what ships.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections import Counter
from dataclasses import replace
from datetime import datetime, timedelta, timezone
from pathlib import Path

from lab.accuracy import CONDITIONS, DJI_QUAD, render_in_world

#: The conditions the site's scenes alternate between (in pairs).
SITE_CONDITIONS = ("cw-hover-tagged", "cw-idle-tagged")
#: The registered serials: the drone, and one of each other shipped model a spoof claims to be.
SERIALS = {DJI_QUAD.slug: "1581FDJQUAD000000001", "m300": "1581FM300STE00000001",
           "m600": "1581FM600STE00000001", "phantom4": "1581FPHANTM400000001"}
VALID_FROM = datetime(2026, 1, 1, tzinfo=timezone.utc)
#: Seconds between a track's dwells.
DWELL_SPACING_S = 1.0


def dwells(k: int, n: int, world: str, serial: str | None, seed: int = 0, start: datetime | None = None,
           carrier_hz: float | None = None) -> list:
    """The first `n` dwells of site scene `k` in `world` (successive simulator seeds), each carrying
    the Remote ID of `serial` (None: none); at `carrier_hz` where given, else the scene's own."""
    from lab.bench.cw_claims import broadcasting

    cond = CONDITIONS[SITE_CONDITIONS[(k // 2) % 2]]
    scene, pre, sim_seed = cond.draw(seed * 100_003 + k)
    if carrier_hz is not None:
        pre = replace(pre, config=pre.config.replace(carrier_hz=float(carrier_hz)))
    start = start or datetime.now(timezone.utc)
    out = []
    for j in range(n):
        rec = render_in_world(world, scene, pre, (sim_seed + 7919 * j) % 2**31)[0]
        rec = replace(rec, start_time=start + timedelta(seconds=j * DWELL_SPACING_S))
        out.append(broadcasting(rec, scene, serial) if serial else rec)
    return out


def write_site(folder: Path, scenes: list[int], world: str, seed: int = 0) -> Path:
    """The enrolment recordings (the first dwell of each scene, the drone's Remote ID) and their
    `labels.csv`; returns the labels file."""
    from signatures.recording import write_recording

    folder.mkdir(parents=True, exist_ok=True)
    rows = ["file,model"]
    for k in scenes:
        rec = dwells(k, 1, world, SERIALS[DJI_QUAD.slug], seed)[0]
        write_recording(rec, folder / f"scene-{k:03d}.h5")
        rows.append(f"scene-{k:03d}.h5,{DJI_QUAD.slug}")
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    return folder / "labels.csv"


def write_raw(folder: Path, scenes: list[int], track_scene: int, track_dwells: int, track_carrier_hz: float,
              world: str = "training", seed: int = 0) -> dict[str, int]:
    """A radar's raw arrays, as `authn import array --domain cw` reads them: per carrier, the first
    dwell of each of `scenes` flown at it, one after the other (`<carrier>GHz.npy`, e.g. `3.30GHz.npy`:
    complex I/Q, one sample per pulse), and `track.npy`: `track_dwells` dwells of `track_scene` at
    `track_carrier_hz`. Returns the dwells written per file."""
    import numpy as np

    folder.mkdir(parents=True, exist_ok=True)
    per: dict[float, list] = {}
    for k in scenes:
        rec = dwells(k, 1, world, None, seed)[0]
        per.setdefault(rec.config.carrier_hz, []).append(rec.iq.reshape(-1))
    counts = {}
    for carrier, parts in sorted(per.items()):
        name = f"{carrier / 1e9:.2f}GHz.npy"
        np.save(folder / name, np.concatenate(parts).astype(np.complex64))
        counts[name] = len(parts)
    track = dwells(track_scene, track_dwells, world, None, seed, carrier_hz=track_carrier_hz)
    np.save(folder / "track.npy", np.concatenate([r.iq.reshape(-1) for r in track]).astype(np.complex64))
    counts["track.npy"] = track_dwells
    return counts


def register_site(db_url: str) -> None:
    """The drone's profile from its physics, and the site's four identities."""
    from registry.dbapi import transaction
    from registry.store import NewIdentity, register_identity, register_profile

    with transaction(db_url) as s:
        register_profile(s, DJI_QUAD)
        for model, serial in SERIALS.items():
            register_identity(s, NewIdentity(serial=serial, model=model, valid_from=VALID_FROM))


def check_tracks(checker, scenes: list[int], n_dwells: int, world: str, seed: int = 0) -> dict:
    """Each scene's track claimed as every registered model (genuine: the drone's own serial), and
    its first dwell alone: decisions counted per claimed model."""
    from authn.track import Dwell, decide_track

    tracks: dict[str, Counter] = {m: Counter() for m in SERIALS}
    single: dict[str, Counter] = {m: Counter() for m in SERIALS}
    rates: dict[str, Counter] = {m: Counter() for m in SERIALS}  # dwells used: own train, at the track's rate
    for k in scenes:
        for model, serial in SERIALS.items():
            recs = dwells(k, n_dwells, world, serial, seed)
            out = decide_track(checker, [Dwell.recording(r, f"scene-{k}-{j}") for j, r in enumerate(recs)])
            tracks[model][out.decision] += 1
            for d in out.dwells:
                rates[model]["used"] += 1
                rates[model]["own_train" if d.flash_rate and "track_rate" not in d.flash_rate else
                             "at_track_rate" if d.flash_rate else "no_rate"] += 1
            single[model][checker.evaluate_recording(recs[0]).decision] += 1
    return {"tracks": {m: dict(c) for m, c in tracks.items()}, "single_dwells": {m: dict(c) for m, c in single.items()},
            "dwell_rates": {m: dict(c) for m, c in rates.items()}}


def run(world: str, n_enrol: int, n_tracks: int, n_dwells: int, seed: int = 0, base_samples: int = 1500,
        heldout_tracks: bool = False) -> dict:
    """Enrol the even scenes with `authn models enrol` (one model), then check the odd scenes'
    tracks; in `world` (`heldout_tracks`: the tracks in the held-out world whatever `world`)."""
    with tempfile.TemporaryDirectory(prefix="one-airframe-") as tmp:
        root = Path(tmp)
        before = os.environ.get("AUTHN_MODELS_DIR")
        os.environ["AUTHN_MODELS_DIR"] = str(root / "models")  # the site's bundles: this run's own
        try:
            return _run(root, world, n_enrol, n_tracks, n_dwells, seed, base_samples, heldout_tracks)
        finally:
            if before is None:
                os.environ.pop("AUTHN_MODELS_DIR", None)
            else:
                os.environ["AUTHN_MODELS_DIR"] = before


def enrol_site(db_url: str, flights: Path, name: str, base_samples: int, seed: int = 0) -> dict:
    """What `authn models enrol FLIGHTS --labels FLIGHTS/labels.csv` does (the drone's recordings
    read and labelled, one waveform over their carriers, the bundle built and made active),
    without the command's printing; returns the card."""
    from authn.enrolment import on_one_waveform, site_sample
    from authn.sprt import Sprt
    from registry.dbapi import Database
    from signatures.train.enrol import EnrolOptions, enrol
    from signatures.classify.inference import models_dir, set_active
    from signatures.profiles import shipped_profiles

    db = Database(db_url)
    read = [site_sample(f, DJI_QUAD.slug, db) for f in sorted(flights.glob("*.h5"))]
    wf, samples, at = on_one_waveform(read)
    carriers = {f: at.count(f) for f in set(at)}
    profiles = {**shipped_profiles(), **{p.slug: p for p in db.registered_profiles()}}
    card = enrol(samples, profiles, wf, models_dir() / name,
                 EnrolOptions(name=name, seed=seed, n_sim=base_samples, sprt=Sprt(), carriers=carriers))
    set_active(wf.key, name)
    return card


def _run(root: Path, world: str, n_enrol: int, n_tracks: int, n_dwells: int, seed: int, base_samples: int,
         heldout_tracks: bool) -> dict:
    from authn.check import Checker
    from lab.bench.cw_claims import cw_site_policy

    db = f"sqlite:///{root / 'site.sqlite3'}"
    register_site(db)
    labels = write_site(root / "flights", [2 * i for i in range(n_enrol)], world, seed)
    t0 = time.perf_counter()
    card = enrol_site(db, labels.parent, f"one-{world}-{seed}", base_samples, seed)["enrolment"]
    enrol_s = time.perf_counter() - t0
    policy = root / "cw-site.cedar"
    policy.write_text(cw_site_policy())
    checker = Checker(db, policy_path=policy)
    t0 = time.perf_counter()
    out = check_tracks(checker, [2 * i + 1 for i in range(n_tracks)], n_dwells, "heldout" if heldout_tracks else world,
                       seed)
    return {"world": world, "tracks_world": "heldout" if heldout_tracks else world, "enrolled": n_enrol,
            "tracks_checked": n_tracks, "dwells": n_dwells, "enrol_seconds": round(enrol_s, 1),
            "card": {k: card[k] for k in ("confusable_pairs", "confusable_pairs_tracks", "signatures", "bands",
                                          "carriers_hz")},
            "card_genuine_tracks": card["tracks"]["genuine_accept"],
            "check_seconds": round(time.perf_counter() - t0, 1), **out}


def main_(argv: list[str] | None = None) -> int:
    from lab.accuracy import WORLDS

    ap = argparse.ArgumentParser(prog="python -m lab.one_airframe", description=__doc__.splitlines()[0])
    ap.add_argument("--world", choices=WORLDS, default="training")
    ap.add_argument("--heldout-tracks", action="store_true", help="check the tracks in the held-out world")
    ap.add_argument("--enrol", type=int, default=20, help="enrolled scenes (the even ones)")
    ap.add_argument("--tracks", type=int, default=20, help="unseen tracks (the odd scenes)")
    ap.add_argument("--dwells", type=int, default=8, help="dwells per track")
    ap.add_argument("--base-samples", type=int, default=1500)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    print(f"# {' '.join(['python -m lab.one_airframe', *(argv if argv is not None else sys.argv[1:])])}")
    print(f"# {datetime.now(timezone.utc).date()}, {os.cpu_count()} cores")
    print(json.dumps(run(a.world, a.enrol, a.tracks, a.dwells, a.seed, a.base_samples, a.heldout_tracks), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main_())
