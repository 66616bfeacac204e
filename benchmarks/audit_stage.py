"""The audit stage of a single check: `timings_ms["audit"]` of `authn check FILE --json`, each
a cold process, on a file-backed SQLite log of --entries entries; and one append in a warm
process on the same log.

    python benchmarks/audit_stage.py [--entries 3000] [--checks 15] [--appends 200]

The log key, STH log and database go to a temporary folder, not the user's.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path


def _flight(folder: Path) -> Path:
    """An M300 broadcasting its registered serial, starting now (decided and audited: exit 4)."""
    from authn.scenario import Broadcast, simulate_flight
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.recording import write_recording
    from signatures.sim.scene import Scene

    scene = Scene(profile=shipped_profiles()["m300"], range_m=400.0, radial_speed_mps=3.0, snr_db=20.0,
                  elevation_deg=10.0)
    rec, _ = simulate_flight(scene, get_preset("paper"), 11, Broadcast(serial="1581BDEM00000002"),
                             azimuth_deg=60.0, start_time=datetime.now(timezone.utc))
    return write_recording(rec, folder / "flight.h5")


def _summary(xs: list[float]) -> str:
    xs = sorted(xs)
    return f"median {statistics.median(xs):.2f} ms, p90 {xs[int(0.9 * (len(xs) - 1))]:.2f} ms (n={len(xs)})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--entries", type=int, default=3000)
    ap.add_argument("--checks", type=int, default=15)
    ap.add_argument("--appends", type=int, default=200)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="authn-audit-stage-"))
    os.environ["AUTHN_LOG_KEY"] = str(tmp / "log.pem")
    os.environ["AUTHN_AUDIT_STH_LOG"] = str(tmp / "sth.jsonl")
    url = f"sqlite:///{tmp / 'registry.sqlite3'}"

    from authn.audit import NewEntry, append
    from authn.demo import register_examples
    from registry.dbapi import Database

    register_examples(url)
    flight = _flight(tmp)
    db = Database(url)
    payload = {"reasons": ["registered-active"], "claim": {"serial": "1581BDEM00000002"}, "n": 0}
    for start in range(0, args.entries, 1000):
        append(db, [NewEntry("decision", "1581BDEM00000002", "accept", {**payload, "n": start + i})
                    for i in range(min(1000, args.entries - start))])
    stage = []
    for _ in range(args.checks):
        out = subprocess.run([sys.executable, "-m", "authn", "--db", url, "check", str(flight), "--json"],
                             capture_output=True, text=True, check=False)
        stage.append(float(json.loads(out.stdout)["timings_ms"]["audit"]))
    print(f"cold `authn check --json`, audit stage: {_summary(stage)}")
    warm = []
    for i in range(args.appends):
        t0 = time.perf_counter()
        append(db, [NewEntry("decision", "1581BDEM00000002", "accept", {**payload, "n": -i})])
        warm.append((time.perf_counter() - t0) * 1e3)
    print(f"warm append of one entry: {_summary(warm)}")
    print(f"log: {int(db.fetch('SELECT COUNT(*) FROM audit_log')[0][0])} entries in {tmp}")


if __name__ == "__main__":
    main()
