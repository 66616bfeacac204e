"""A CW radar's identity claims end to end, on our CW worlds (docs/policies.md, "A CW radar's claims, measured").

The real-radar scenario: a DJI-class quadcopter (`lab.accuracy.DJI_QUAD`, a profile no classifier
knows) registered from its physics, a bundle trained for the radar's waveform (`authn models train
--radar-config`), a site policy that takes CW evidence (the default less `range-not-measured`: a CW
radar measures no range, so the default rejects every claim that declares a position), and the dwells
of a real-radar condition (`lab.accuracy.CONDITIONS`: hovering, tagged blades, strong clutter) in
each world, each carrying the drone's Remote ID. Every dwell is checked by the real `Checker` twice:
claiming the drone's own serial (genuine) and claiming a registered Phantom 4's serial (an impostor
with the very same return). Reported per condition and world: genuine claims accepted, impostor
claims rejected, the reasons, and how often the physics term abstained (then the claim cannot be
accepted on radar evidence: `radar-unverifiable`).

    authn models train --radar-config radar335.json --samples 2000 --test-samples 50 --out cw335
    python -m lab.bench.cw_claims --model cw335 --condition cw-hover-tagged --n 40 --world training --world heldout

Nothing here is tuned on; it measures what ships.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
from collections import Counter
from dataclasses import asdict, dataclass, replace
from datetime import datetime, timezone
from pathlib import Path

#: The serials of the bench's registry: the drone flown, and a Phantom 4 an impostor claims to be.
GENUINE_SERIAL = "1581FDJQUAD000000001"
IMPOSTOR_SERIAL = "1581FPHANTM400000001"
VALID_FROM = datetime(2026, 1, 1, tzinfo=timezone.utc)
#: The forbid a site taking CW evidence drops (authn/policies/default.cedar).
CW_DROPPED_FORBID = "range-not-measured"


@dataclass(frozen=True)
class ClaimRow:
    """One condition in one world: shares of n dwells."""

    condition: str
    world: str
    n: int
    genuine_accepted: float
    impostor_rejected: float
    physics_abstained: float  # the genuine claims' physics term left out (no rate evidence)
    genuine_reasons: str  # the most frequent reasons of genuine claims, with counts
    impostor_reasons: str  # of impostor claims
    seconds: float


def cw_site_policy() -> str:
    """The shipped default policy without `CW_DROPPED_FORBID`: what a site that takes CW evidence
    (type and radial velocity only) runs."""
    from importlib.resources import files

    text = files("authn.policies").joinpath("default.cedar").read_text()
    dropped, n = re.subn(r'@id\("' + CW_DROPPED_FORBID + r'"\)\s*forbid\s*\(.*?\n\};\n', "", text, flags=re.S)
    if n != 1:
        raise RuntimeError(f"the default policy holds {n} `{CW_DROPPED_FORBID}` forbids, 1 expected")
    return dropped


def bench_registry(db_url: str) -> None:
    """The drone's profile from its physics, its identity and a Phantom 4's."""
    from lab.accuracy import DJI_QUAD
    from registry.dbapi import transaction
    from registry.store import NewIdentity, register_identity, register_profile

    with transaction(db_url) as s:
        register_profile(s, DJI_QUAD)
        register_identity(s, NewIdentity(serial=GENUINE_SERIAL, model=DJI_QUAD.slug, valid_from=VALID_FROM))
        register_identity(s, NewIdentity(serial=IMPOSTOR_SERIAL, model="phantom4", valid_from=VALID_FROM))


def broadcasting(rec, scene, serial: str):
    """`rec` carrying the Remote ID of a drone at the scene's position declaring `serial`."""
    from authn.scenario import Broadcast, remote_id_rows

    rid, times = remote_id_rows(rec, scene, Broadcast(serial=serial), 0.0, rec.n_chirps * rec.config.pri_s)
    return replace(rec, remote_id=rid, remote_id_time_s=times)


def _top(reasons: Counter, k: int = 3) -> str:
    return ", ".join(f"{r} {c}" for r, c in reasons.most_common(k)) or "-"


def run(model: Path, conditions: list[str], worlds: list[str], n: int, seed: int = 0) -> list[ClaimRow]:
    """Each condition in each world: n seeded dwells (the scenes `authn features accuracy
    --condition` scores), each checked as genuine and as an impostor's claim."""
    from authn.check import Checker
    from lab.accuracy import CONDITIONS, render_condition

    rows = []
    with tempfile.TemporaryDirectory(prefix="cw-claims-") as tmp:
        db = f"sqlite:///{os.path.join(tmp, 'bench.sqlite3')}"
        bench_registry(db)
        policy = Path(tmp) / "cw-site.cedar"
        policy.write_text(cw_site_policy())
        checker = Checker(db, policy_path=policy, model=model)
        for name in conditions:
            for world in worlds:
                t0 = time.perf_counter()
                genuine, impostor, abstained = 0, 0, 0
                reasons_g: Counter = Counter()
                reasons_i: Counter = Counter()
                for i in range(n):
                    rec, scene, _, _, _ = render_condition(CONDITIONS[name], world, seed * 100_003 + i)
                    g, im = (checker.evaluate_recording(broadcasting(rec, scene, serial))
                             for serial in (GENUINE_SERIAL, IMPOSTOR_SERIAL))
                    genuine += g.decision == "accept"
                    impostor += im.decision != "accept"
                    verification = g.radar.verification if g.radar else None
                    abstained += verification is None or verification.physics_abstained
                    reasons_g.update(g.reasons)
                    reasons_i.update(im.reasons)
                rows.append(ClaimRow(name, world, n, genuine / n, impostor / n, abstained / n, _top(reasons_g),
                                     _top(reasons_i), time.perf_counter() - t0))
    return rows


def table(rows: list[ClaimRow]) -> list[str]:
    lines = ["| condition | world | n | genuine accepted | impostor (Phantom 4's serial) rejected | physics abstained "
             "| genuine reasons | impostor reasons |", "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r.condition} | {r.world} | {r.n} | {r.genuine_accepted:.0%} | {r.impostor_rejected:.0%} | "
              f"{r.physics_abstained:.0%} | {r.genuine_reasons} | {r.impostor_reasons} |" for r in rows]
    return lines


def main(argv: list[str] | None = None) -> int:
    from lab.accuracy import CONDITIONS, WORLDS

    ap = argparse.ArgumentParser(prog="python -m lab.bench.cw_claims", description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True, type=Path, help="a bundle trained for the conditions' waveform")
    ap.add_argument("--condition", action="append", choices=tuple(CONDITIONS), help="repeatable")
    ap.add_argument("--world", action="append", choices=WORLDS, help="repeatable (default training)")
    ap.add_argument("--n", type=int, default=40, help="dwells per condition and world")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", help="write the rows to this file")
    a = ap.parse_args(argv)
    if a.n < 1:
        ap.error(f"--n {a.n}: at least 1")
    print(f"# {' '.join(['python -m lab.bench.cw_claims', *(argv if argv is not None else sys.argv[1:])])}")
    print(f"# {datetime.now(timezone.utc).date()}, {os.cpu_count()} cores")
    rows = run(a.model, a.condition or ["cw-hover-tagged"], a.world or ["training"], a.n, a.seed)
    print("\n".join(table(rows)))
    if a.json:
        import json

        Path(a.json).write_text(json.dumps([asdict(r) for r in rows]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
