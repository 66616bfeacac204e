"""End-to-end benchmark: decisions on simulated claims over random geometry, and latency.

Categories: genuine claims, type spoofs between the shipped
profiles, position spoofs (Remote ID displaced 100-300 m along the line of sight),
unregistered and revoked serials; then signed Remote ID (IETF DRIP, RFC 9575) against
identities registered with a key: a genuine signed flight, an unsigned claim of a keyed
identity by a drone of the same type (what the radar cannot see), a forgery (another key
signing in the victim's DET) and a replay (the victim's own signature, a day old). Each
scene is a real file checked by the real `Checker` against a real (temporary SQLite)
registry; the DRIP keys are generated for each run.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from authn.scenario import Broadcast, Signing, simulate_flight
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.sim.sampling import SceneDistribution, sample_scene
from signatures.sim.scene import Scene

if TYPE_CHECKING:
    from authn.uakeys import UaKey

DRIP_CATEGORIES = ("drip_genuine", "drip_unsigned", "drip_forged", "drip_replayed")
CATEGORIES = ("genuine", "type_spoof", "position_spoof", "unregistered", "revoked", *DRIP_CATEGORIES)
ACCEPTED = ("genuine", "drip_genuine")
EXPECTED = {c: "accept" if c in ACCEPTED else "reject" for c in CATEGORIES}


def is_right(expected: str, decision: str) -> bool:
    """A claim that must be accepted is right when accepted; one that must not, when not accepted
    (rejected, or inconclusive: neither lets it through)."""
    return decision == "accept" if expected == "accept" else decision != "accept"
#: the reason each DRIP rejection must carry (the policy's @id)
DRIP_REASONS = {"drip_unsigned": "remote-id-auth-required", "drip_forged": "remote-id-auth-invalid",
                "drip_replayed": "remote-id-auth-expired"}
#: categories whose drone signs its Remote ID (the rest broadcast unsigned)
SIGNED = ("drip_genuine", "drip_forged", "drip_replayed")
REPLAY_AGE_S = 86400.0
VALID_FROM = datetime(2025, 1, 1, tzinfo=timezone.utc)
UNREGISTERED = "1581BBENCH99999X"


def bench_serial(slug: str, revoked: bool = False) -> str:
    return {"m600": "1581BBENCH00600", "m300": "1581BBENCH00300", "phantom4": "1581BBENCH00004"}[slug] \
        + ("R" if revoked else "A")


def keyed_serial(slug: str) -> str:
    """The serial of `slug`'s identity registered with a DRIP key."""
    return bench_serial(slug)[:-1] + "K"


def register_identities(db_url: str, keys: "dict[str, UaKey] | None" = None) -> None:
    """An active and a revoked identity per shipped profile; with `keys` (slug -> key) also a
    keyed one per slug (`keyed_serial`) holding that key's public half."""
    from registry.dbapi import transaction
    from registry.store import NewIdentity, register_identity, revoke_identity

    with transaction(db_url) as s:
        for slug in shipped_profiles():
            for revoked in (False, True):
                register_identity(s, NewIdentity(serial=bench_serial(slug, revoked), model=slug, valid_from=VALID_FROM))
                if revoked:
                    revoke_identity(s, bench_serial(slug, revoked), "bench")
        for slug, key in (keys or {}).items():
            register_identity(s, NewIdentity(serial=keyed_serial(slug), model=slug, public_key=key.public_raw,
                                             valid_from=VALID_FROM))


def drip_broadcast(cat: str, serial: str, offset: float, victim: "UaKey", attacker: "UaKey") -> Broadcast:
    """The Remote ID of a DRIP category's drone claiming `serial` (registered with `victim`'s key)."""
    signing = {"drip_genuine": Signing(private_key=victim.private_raw, det=victim.det),
               "drip_forged": Signing(private_key=attacker.private_raw, det=victim.det),
               "drip_replayed": Signing(private_key=victim.private_raw, det=victim.det,
                                        signed_at_offset_s=-REPLAY_AGE_S)}.get(cat)
    return Broadcast(serial=serial, offset_along_los_m=offset, signing=signing)


@dataclass
class Row:
    preset: str
    category: str
    n: int
    correct: int
    radar_skipped: int
    median_ms: float
    wrong_reasons: dict[str, int]  # reasons of the decisions that went the wrong way
    auth_ms: list[float] = field(default_factory=list)  # each check's remote_id_auth stage (DRIP verification)
    reason_missing: int = 0  # DRIP rejections without their category's reason (`DRIP_REASONS`)
    wrong_pairs: dict[str, int] = field(default_factory=dict)  # "flown->claimed" of the wrong decisions
    inconclusive: int = 0  # decisions the evidence left undecided (never an accept)

    @property
    def median_auth_ms(self) -> float:
        return statistics.median(self.auth_ms) if self.auth_ms else float("nan")

    @property
    def rate(self) -> float:
        return self.correct / self.n if self.n else float("nan")


#: Scenes of the claims checked here (and timed by `perf`): a UAV anywhere from 60 m to 1.1 km,
#: 30 % hovering, and clutter in 70 % of them; the SNR span is the caller's.
CLAIM_SCENES = SceneDistribution(order=("speed", "range", "elevation", "snr", "clutter"), range_m=(60.0, 1100.0),
                                 elevation_deg=(0.0, 40.0), hover_fraction=0.3, speed_mps=(1.0, 15.0),
                                 snr_db=(10.0, 30.0), clutter_band=(0.3, 1.0), clutter_db=(0.0, 20.0))


def random_scene(rng: np.random.Generator, slug: str, snr_range: tuple[float, float]) -> tuple[Scene, float]:
    """A claim's scene (`CLAIM_SCENES` with SNR uniform over `snr_range`) and a radar azimuth."""
    scene = sample_scene(rng, shipped_profiles()[slug], replace(CLAIM_SCENES, snr_db=snr_range))
    return scene, float(rng.uniform(0.0, 360.0))


def run_decisions(presets: tuple[str, ...], n: int, seed: int, snr_range: tuple[float, float] = (10.0, 30.0),
                  progress: Callable[[int], None] | None = None) -> list[Row]:
    """n scenes per category and preset; returns one row per (preset, category)."""
    from authn import uakeys
    from authn.check import Checker

    slugs = list(shipped_profiles())
    keys = {slug: uakeys.generate() for slug in slugs}
    attacker = uakeys.generate()
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        db = f"sqlite:///{Path(tmp) / 'bench.sqlite3'}"
        register_identities(db, keys)
        checker = Checker(db)
        now = datetime.now(timezone.utc)
        for preset in presets:
            pre = get_preset(preset)
            rng = np.random.default_rng([seed, len(preset)])
            for cat in CATEGORIES:
                correct = skipped = missing = unsure = 0
                times, auth = [], []
                wrong: dict[str, int] = defaultdict(int)
                pairs: dict[str, int] = defaultdict(int)
                for i in range(n):
                    flies = slugs[i % len(slugs)]
                    claims = flies
                    offset = 0.0
                    if cat == "type_spoof":
                        claims = slugs[(i + 1 + (i // 3) % 2) % len(slugs)]
                    if cat == "position_spoof":
                        offset = float(rng.choice([-1, 1]) * rng.uniform(100.0, 300.0))
                    serial = {"unregistered": UNREGISTERED, "revoked": bench_serial(claims, True)}.get(
                        cat, keyed_serial(claims) if cat in DRIP_CATEGORIES else bench_serial(claims))
                    scene, az = random_scene(rng, flies, snr_range)
                    if offset < 0 and scene.range_m + offset < 30.0:
                        offset = -offset
                    bc = (drip_broadcast(cat, serial, offset, keys[claims], attacker) if cat in DRIP_CATEGORIES
                          else Broadcast(serial=serial, offset_along_los_m=offset))
                    rec, _ = simulate_flight(scene, pre, int(rng.integers(2**31)), bc, azimuth_deg=az,
                                             start_time=now)
                    path = write_recording(rec, Path(tmp) / "scene.h5")
                    t0 = time.perf_counter()
                    out = checker.evaluate(path)
                    times.append((time.perf_counter() - t0) * 1e3)
                    auth.append(out.timings_ms["remote_id_auth"])
                    missing += cat in DRIP_REASONS and DRIP_REASONS[cat] not in out.reasons
                    correct += is_right(EXPECTED[cat], out.decision)
                    skipped += out.radar is None
                    unsure += out.decision == "inconclusive"
                    if not is_right(EXPECTED[cat], out.decision):
                        wrong[",".join(out.reasons)] += 1
                        pairs[f"{flies}->{claims}"] += 1
                    if progress:
                        progress(1)
                rows.append(Row(preset, cat, n, correct, skipped, statistics.median(times), dict(wrong), auth,
                                missing, dict(pairs), unsure))
    return rows


def ensure_bytecode() -> None:
    """Compile our packages' bytecode, as `pip install` does for a regular install.

    An editable install run with PYTHONDONTWRITEBYTECODE=1 (this project's machines) would
    otherwise recompile every module of ours in every process: ~40 ms of a cold check.
    """
    import compileall
    import importlib.util

    for pkg in ("core", "authn", "signatures", "registry", "lab"):
        spec = importlib.util.find_spec(pkg)
        if spec is not None and spec.submodule_search_locations:
            for folder in spec.submodule_search_locations:
                compileall.compile_dir(folder, quiet=1)


_FIRST_CHECK = """
import json, sys, time
from authn.check import Checker
checker = Checker(sys.argv[1])
t0 = time.perf_counter()
checker.record([checker.evaluate(sys.argv[2], sys.argv[3])])
print(json.dumps((time.perf_counter() - t0) * 1e3))
"""


def _run_ms(args: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(args, capture_output=True, check=False)
    return (time.perf_counter() - t0) * 1e3


def cold_times(path: Path, serial: str, db_url: str, repeats: int = 11) -> dict[str, float]:
    """Fresh processes, interleaved so they share the machine's state: `python -c 'import numpy'`,
    a whole `authn check` (genuine claim, radar run) and a registry-only rejection (unregistered
    serial), medians; plus each check's own time in a fresh process after start-up (imports of
    `authn.check` and the policy load excluded; loading the radar modules and models included)."""
    ensure_bytecode()
    check = [sys.executable, "-m", "authn", "--db", db_url, "check", str(path), "--json", "--serial"]
    first = [sys.executable, "-c", _FIRST_CHECK, db_url, str(path)]
    runs: dict[str, list[float]] = defaultdict(list)
    for _ in range(repeats):
        runs["import_numpy_ms"].append(_run_ms([sys.executable, "-c", "import numpy"]))
        runs["cold_process_ms"].append(_run_ms(check + [serial]))
        runs["cold_registry_only_ms"].append(_run_ms(check + [UNREGISTERED]))
        for key, who in (("first_check_ms", serial), ("first_registry_only_ms", UNREGISTERED)):
            out = subprocess.run(first + [who], capture_output=True, text=True, check=True)
            runs[key].append(float(out.stdout.strip().splitlines()[-1]))
    med = {k: statistics.median(v) for k, v in runs.items()}
    med["cold_vs_import_numpy"] = med["cold_process_ms"] / med["import_numpy_ms"]
    med["first_registry_only_vs_full"] = med["first_registry_only_ms"] / med["first_check_ms"]
    return med


def latency(preset: str, n_batch: int, seed: int, repeats: int = 11) -> dict[str, float]:
    """Cold processes (see `cold_times`) and one check inside batch mode (models loaded once),
    genuine claims."""
    from authn.check import Checker

    with tempfile.TemporaryDirectory() as tmp:
        db = f"sqlite:///{Path(tmp) / 'lat.sqlite3'}"
        register_identities(db)
        rng = np.random.default_rng(seed)
        pre = get_preset(preset)
        paths = []
        for i in range(n_batch):
            scene, az = random_scene(rng, "m300", (10.0, 30.0))
            rec, _ = simulate_flight(scene, pre, i, Broadcast(serial=bench_serial("m300")), azimuth_deg=az,
                                     start_time=datetime.now(timezone.utc))
            paths.append(write_recording(rec, Path(tmp) / f"s{i}.h5"))
        checker = Checker(db)
        checker.record([checker.evaluate(paths[0])])  # warm: models and policy loaded once
        per = []
        for p in paths:
            t0 = time.perf_counter()
            checker.record([checker.evaluate(p)])
            per.append((time.perf_counter() - t0) * 1e3)
        return {"batch_ms_per_check": statistics.median(per),
                **cold_times(paths[0], bench_serial("m300"), db, repeats)}


def summarise(rows: list[Row]) -> dict[str, dict[str, dict[str, float]]]:
    out: dict[str, dict[str, dict[str, float]]] = defaultdict(dict)
    for r in rows:
        out[r.preset][r.category] = {"n": r.n, "correct_rate": r.rate, "radar_skipped_rate": r.radar_skipped / r.n,
                                     "inconclusive_rate": r.inconclusive / r.n,
                                     "median_check_ms": round(r.median_ms, 2), "wrong_reasons": r.wrong_reasons,
                                     "wrong_pairs": r.wrong_pairs,
                                     "median_remote_id_auth_ms": round(r.median_auth_ms, 4)}
        if r.category in DRIP_REASONS:
            out[r.preset][r.category]["reason_missing"] = r.reason_missing
    return dict(out)


def drip_cost(rows: list[Row]) -> dict[str, dict[str, float]]:
    """Per preset, the check's `remote_id_auth` stage (DRIP verification): median over the
    genuine signed checks (a valid signature, the cost a signed flight adds), over the forged
    and replayed ones, and over every unsigned check (finding there is nothing to verify)."""
    out: dict[str, dict[str, float]] = {}
    for preset in dict.fromkeys(r.preset for r in rows):
        pools = {"signed_valid": [r for r in rows if r.category == "drip_genuine"],
                 "signed_rejected": [r for r in rows if r.category in ("drip_forged", "drip_replayed")],
                 "unsigned": [r for r in rows if r.category not in SIGNED]}
        doc: dict[str, float] = {}
        for name, group in pools.items():
            times = [t for r in group if r.preset == preset for t in r.auth_ms]
            doc[f"{name}_ms"] = round(statistics.median(times), 4) if times else float("nan")
            doc[f"{name}_n"] = len(times)
        doc["signed_minus_unsigned_ms"] = round(doc["signed_valid_ms"] - doc["unsigned_ms"], 4)
        out[preset] = doc
    return out
