"""A simulated paper-preset scene with no range gate (a TI radar has none), a registry
with the shipped example identities, and a CLI runner that returns (exit code, stdout, stderr)."""

from __future__ import annotations

import json
from datetime import datetime, timezone

import pytest

from authn.cli import main
from authn.demo import register_examples
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate

M300 = "1581BDEM00000002"  # registered as an M300 by register_examples


@pytest.fixture(scope="package")
def scene_rec():
    """An M300 at 40 m, 3 m/s receding, 20 dB: window 0..80 m (range offset 0), start now."""
    now = datetime.now(timezone.utc).replace(microsecond=0)
    scene = Scene(profile=shipped_profiles()["m300"], range_m=40.0, radial_speed_mps=3.0, snr_db=20.0)
    rec, _ = simulate(scene, get_preset("paper"), seed=5, range_offset_m=0.0, start_time=now)
    return rec


@pytest.fixture(scope="package")
def registry_db(tmp_path_factory) -> str:
    db = f"sqlite:///{tmp_path_factory.mktemp('importers') / 'r.sqlite3'}"
    register_examples(db)
    return db


@pytest.fixture
def cli(capsys):
    def run(*args: str) -> tuple[int, str, str]:
        capsys.readouterr()
        code = main(list(args))
        out = capsys.readouterr()
        return code, out.out, out.err
    return run


def site_args(rec) -> list[str]:
    return ["--start-time", rec.start_time.isoformat(), "--site-lat", repr(rec.site.lat_deg),
            "--site-lon", repr(rec.site.lon_deg), "--site-alt", repr(rec.site.alt_m)]


def check_json(cli, db: str, path, serial: str = M300) -> tuple[int, dict]:
    """`authn check FILE --serial SERIAL --json`: a decision (0 accept, 1 reject, 4 inconclusive:
    one unsigned dwell at the default targets crosses neither bound of the sequential test), not
    an error; its exit code and JSON object."""
    code, out, err = cli("--db", db, "check", str(path), "--serial", serial, "--json")
    assert code in (0, 1, 4), err  # a decision: accept, reject or inconclusive
    return code, json.loads(out)
