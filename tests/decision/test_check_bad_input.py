"""Every malformed input reaching `authn check`: exit 2, one line on stderr, an audit error entry."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from authn.cli import main
from authn.scenario import Broadcast, simulate_flight
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.sim.scene import Scene
from tests.remoteid.capture_tools import heard_at

SERIAL = "1581BDEM00000002"


@pytest.fixture(scope="module")
def good_file(tmp_path_factory) -> Path:
    scene = Scene(profile=shipped_profiles()["m300"], range_m=300.0, radial_speed_mps=2.0, snr_db=15.0)
    rec, _ = simulate_flight(scene, get_preset("paper"), 3, Broadcast(serial=SERIAL))
    return write_recording(rec, tmp_path_factory.mktemp("good") / "good.h5")


def _variant(src: Path, dst: Path, **edit) -> Path:
    dst.write_bytes(src.read_bytes())
    with h5py.File(dst, "a") as f:
        for k, v in edit.get("attrs", {}).items():
            f.attrs[k] = v
        for name, data in edit.get("datasets", {}).items():
            if name in f:
                del f[name]
            if data is not None:
                f.create_dataset(name, data=data)
    return dst


def _garbage_rid() -> np.ndarray:
    rows = np.zeros((2, 25), np.uint8)
    rows[0, 0] = 0x62  # message type 6 does not exist
    rows[1, 0] = 0x02
    return rows


CASES = {
    "missing file": lambda src, d: d / "nope.h5",
    "truncated": lambda src, d: (d / "cut.h5").write_bytes(src.read_bytes()[:3000]) and d / "cut.h5",
    "format tag": lambda src, d: _variant(src, d / "fmt.h5", attrs={"format": "other/2"}),
    "pri below ramp": lambda src, d: _variant(src, d / "pri.h5", attrs={"pri_s": 1e-9}),
    "NaN iq": lambda src, d: _variant(src, d / "nan.h5", datasets={"iq": np.full((4, 8), np.nan, np.complex64)}),
    "remote id width": lambda src, d: _variant(src, d / "w.h5", datasets={"remote_id_time_s": None,
                                                                         "remote_id": np.zeros((2, 24), np.uint8)}),
    "malformed remote id": lambda src, d: _variant(src, d / "rid.h5", datasets={"remote_id_time_s": None,
                                                                               "remote_id": _garbage_rid()}),
    "no claim at all": lambda src, d: _variant(src, d / "noclaim.h5",
                                               datasets={"remote_id_time_s": None, "remote_id": None}),
    # message times no datetime can hold (OverflowError, exit 3), or centuries from the dwell
    **{f"capture time {v!r}": (lambda src, d, v=v: heard_at(src, d / "t.h5", v))
       for v in (1e15, -1e15, 1.7e308, 2**62, 1e10)},
}


def _err(capsys) -> str:
    """stderr without the notice that the check created the (fresh) test database."""
    return "".join(line for line in capsys.readouterr().err.splitlines(keepends=True)
                   if not line.startswith("authn: created new database "))


def _audit(db: str, capsys) -> list[dict]:
    capsys.readouterr()
    assert main(["--db", db, "audit", "list", "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_exit_2_and_audited(good_file: Path, tmp_path: Path, case: str, capsys) -> None:
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    path = CASES[case](good_file, tmp_path)
    assert main(["--db", db, "check", str(path)]) == 2
    err = _err(capsys)
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err
    entries = _audit(db, capsys)
    assert [e["kind"] for e in entries] == ["error"]
    assert entries[0]["payload"]["file"] == str(path)
    assert main(["--db", db, "audit", "verify"]) == 0


def test_unknown_waveform_and_bad_serial(good_file: Path, tmp_path: Path, capsys) -> None:
    """A waveform no model was trained for, and a malformed --serial: exit 2, audited."""
    from authn.demo import register_examples

    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_examples(db)
    odd = _variant(good_file, tmp_path / "odd.h5", attrs={"carrier_hz": 24e9})
    assert main(["--db", db, "check", str(odd), "--serial", SERIAL]) == 2
    assert "no classifier for this waveform" in capsys.readouterr().err
    assert main(["--db", db, "check", str(good_file), "--serial", "has space"]) == 2
    assert "--serial" in capsys.readouterr().err
    assert [e["kind"] for e in _audit(db, capsys)] == ["error", "error"]


def test_invalid_policy_file_is_refused(good_file: Path, tmp_path: Path, capsys) -> None:
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    bad = tmp_path / "bad.cedar"
    bad.write_text('permit (principal, action, resource) when { context.nope };')
    assert main(["--db", db, "check", str(good_file), "--policy", str(bad)]) == 2
    err = _err(capsys)
    assert "does not validate against the schema" in err and err.count("\n") == 1
    assert [e["kind"] for e in _audit(db, capsys)] == ["error"]


@pytest.mark.parametrize("cli_serial,reasons", [
    (None, ["unregistered"]),
    ("1581BDEM00000099", ["remote-id-implausible", "unregistered"]),  # also differs from its Remote ID
])
def test_registry_rejection_skips_radar(good_file: Path, tmp_path: Path, cli_serial: str | None,
                                        reasons: list[str], capsys) -> None:
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    args = ["--serial", cli_serial] if cli_serial else []
    assert main(["--db", db, "check", str(good_file), "--json", *args]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["decision"] == "reject" and out["reasons"] == reasons
    assert out["radar"] is None and out["kinematics"] is None
    assert set(out["skipped"]) == {"radar_features", "classify", "kinematics"}
    assert out["claim"] == {"serial": cli_serial or SERIAL, "source": "cli" if cli_serial else "remote_id",
                            "remote_id_serial": SERIAL}
    assert out["audit_id"] == 1 and "radar_features" not in out["timings_ms"]


def test_batch_error_lines_name_the_file_once(tmp_path, capsys) -> None:
    """`error: fake.h5: ...`, not `error: fake.h5: fake.h5: ...` (the reader names the file)."""
    from authn.cli import main

    a, b = tmp_path / "fake-a.h5", tmp_path / "fake-b.h5"
    a.write_bytes(b"junk")
    b.write_bytes(b"junk too")
    assert main(["--db", f"sqlite:///{tmp_path / 'r.sqlite3'}", "check", str(a), str(b)]) == 2
    lines = [x for x in capsys.readouterr().err.splitlines() if x.startswith("error: ")]
    assert len(lines) == 2 and all(x.count("fake-") == 1 for x in lines), lines


def test_json_reports_a_bad_file_as_json_one_file_or_many(tmp_path, capsys) -> None:
    """With --json a bad file is `{"file", "error", "exit_code"}` on stdout whether it is checked
    alone or in a batch (system faults stay on stderr: stdout holds only what was audited)."""
    import json

    from authn.cli import main

    bad = tmp_path / "fake.h5"
    bad.write_bytes(b"junk")
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    capsys.readouterr()
    assert main(["--db", db, "check", str(bad), "--json"]) == 2
    alone = json.loads(capsys.readouterr().out)
    assert main(["--db", db, "check", str(bad), str(bad), "--json"]) == 2
    batch = json.loads(capsys.readouterr().out)
    assert alone == batch[0] and alone["exit_code"] == 2 and "not a readable HDF5 file" in alone["error"]
