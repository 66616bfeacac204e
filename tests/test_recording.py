"""Recorded-return files: round trips and every bad-file case (docs/format.md)."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from authn.cli import main
from signatures.errors import RecordingError
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import read_recording, write_recording
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate


@pytest.fixture(scope="module")
def recording():
    scene = Scene(profile=shipped_profiles()["m300"], range_m=300.0, radial_speed_mps=3.0, snr_db=10.0)
    rec, _ = simulate(scene, get_preset("paper"), seed=7)
    rid = np.arange(2 * 25, dtype=np.uint8).reshape(2, 25)
    return rec.__class__(rec.config, rec.site, rec.start_time, rec.iq, rid,
                         np.array([0.1, 0.6]), rec.simulation)


@pytest.mark.parametrize("suffix", [".h5", ".npz"])
def test_round_trip_is_identical(recording, tmp_path: Path, suffix: str) -> None:
    path = write_recording(recording, tmp_path / f"r{suffix}")
    back = read_recording(path)
    assert back.iq.dtype == recording.iq.dtype
    assert np.array_equal(back.iq, recording.iq)
    assert back.config == recording.config
    assert back.site == recording.site
    assert back.start_time == recording.start_time
    assert np.array_equal(back.remote_id, recording.remote_id)
    assert np.array_equal(back.remote_id_time_s, recording.remote_id_time_s)
    assert back.simulation == recording.simulation


def _h5(path: Path, recording, *, drop: str | None = None, attrs: dict | None = None,
        iq: np.ndarray | None = None, rid: np.ndarray | None = None) -> Path:
    write_recording(recording, path)
    with h5py.File(path, "a") as f:
        if drop:
            del f.attrs[drop]
        for k, v in (attrs or {}).items():
            f.attrs[k] = v
        if iq is not None:
            del f["iq"]
            f.create_dataset("iq", data=iq)
        if rid is not None:
            del f["remote_id"]
            del f["remote_id_time_s"]
            f.create_dataset("remote_id", data=rid)
    return path


BAD_CASES = {
    "format tag": (dict(attrs={"format": "uav-radar-return/9"}), "attribute 'format'"),
    "missing attribute": (dict(drop="sample_rate_hz"), "missing attribute 'sample_rate_hz'"),
    "non-positive bandwidth": (dict(attrs={"bandwidth_hz": -1.0}), "attribute 'bandwidth_hz'"),
    "pri below ramp": (dict(attrs={"pri_s": 1e-6}), "pri_s"),
    "string where number": (dict(attrs={"carrier_hz": "77 GHz"}), "attribute 'carrier_hz'"),
    "bad start time": (dict(attrs={"start_time": "yesterday"}), "attribute 'start_time'"),
    "3-D iq": (dict(iq=np.zeros((2, 3, 4), np.complex64)), "dataset '/iq': expected 2-D"),
    "real iq": (dict(iq=np.zeros((4, 8), np.float32)), "dataset '/iq': expected complex64"),
    "NaN in iq": (dict(iq=np.full((4, 8), np.nan, np.complex64)), "non-finite"),
    "Inf in iq": (dict(iq=np.array([[np.inf + 0j, 1]], np.complex128)), "non-finite"),
    "remote id width": (dict(rid=np.zeros((3, 24), np.uint8)), "dataset '/remote_id'"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_file_gets_specific_error_and_exit_2(recording, tmp_path: Path, case: str, capsys) -> None:
    kwargs, expected = BAD_CASES[case]
    path = _h5(tmp_path / "bad.h5", recording, **kwargs)
    with pytest.raises(RecordingError, match=expected.replace("(", r"\(").replace("[", r"\[")):
        read_recording(path)
    assert main(["inspect", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "\n" not in err and expected in err


def test_truncated_file_is_refused(recording, tmp_path: Path, capsys) -> None:
    path = write_recording(recording, tmp_path / "full.h5")
    cut = tmp_path / "cut.h5"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(RecordingError, match="truncated or corrupt"):
        read_recording(cut)
    assert main(["inspect", str(cut)]) == 2
    npz = write_recording(recording, tmp_path / "full.npz")
    cut_npz = tmp_path / "cut.npz"
    cut_npz.write_bytes(npz.read_bytes()[:1000])
    with pytest.raises(RecordingError, match="truncated or corrupt"):
        read_recording(cut_npz)


def test_shape_is_checked_before_loading(recording, tmp_path: Path) -> None:
    """A huge declared cube is refused from its header, without allocating it."""
    path = tmp_path / "huge.h5"
    write_recording(recording, path)
    with h5py.File(path, "a") as f:
        del f["iq"]
        f.create_dataset("iq", shape=(1 << 20, 1 << 16), dtype=np.complex64)  # 512 GiB, never written
    with pytest.raises(RecordingError, match="exceed the limit"):
        read_recording(path)


def test_npz_header_checked_and_no_pickle(recording, tmp_path: Path) -> None:
    path = tmp_path / "obj.npz"
    arrays = {k: np.asarray(v) for k, v in {"format": "uav-radar-return/1"}.items()}
    arrays["iq"] = np.array([[object()]], dtype=object)
    np.savez(path, **arrays)
    with pytest.raises(RecordingError, match="expected complex64"):
        read_recording(path)


def test_not_a_recording(tmp_path: Path) -> None:
    path = tmp_path / "x.bin"
    path.write_bytes(b"hello world")
    with pytest.raises(RecordingError, match="neither HDF5 nor .npz"):
        read_recording(path)


# --- domain (docs/format.md "domain") ---------------------------------------------------

@pytest.mark.parametrize("suffix", [".h5", ".npz"])
@pytest.mark.parametrize("domain,cols", [("range", 80), ("cw", 1)])
def test_domain_round_trip_and_format_tag(recording, tmp_path: Path, suffix: str, domain: str, cols: int) -> None:
    rec = recording.__class__(recording.config, recording.site, recording.start_time, recording.iq[:, :cols],
                              domain=domain)
    path = write_recording(rec, tmp_path / f"d{suffix}")
    back = read_recording(path)
    assert back.domain == domain and np.array_equal(back.iq, rec.iq)
    if suffix == ".h5":
        with h5py.File(path) as f:
            assert f.attrs["format"] == "uav-radar-return/2" and f.attrs["domain"] == domain


def test_if_files_keep_version_1_and_absent_domain_is_if(recording, tmp_path: Path) -> None:
    path = write_recording(recording, tmp_path / "if.h5")
    with h5py.File(path, "a") as f:
        assert f.attrs["format"] == "uav-radar-return/1" and f.attrs["domain"] == "if"
        del f.attrs["domain"]
    assert read_recording(path).domain == "if"


DOMAIN_BAD = {
    "unknown domain": (dict(attrs={"format": "uav-radar-return/2", "domain": "doppler"}), "attribute 'domain'"),
    "numeric domain": (dict(attrs={"format": "uav-radar-return/2", "domain": 3}), "attribute 'domain'"),
    "range under version 1": (dict(attrs={"domain": "range"}), "needs format 'uav-radar-return/2'"),
    "cw with many columns": (dict(attrs={"format": "uav-radar-return/2", "domain": "cw"}), "a 'cw' recording"),
}


@pytest.mark.parametrize("case", sorted(DOMAIN_BAD))
@pytest.mark.parametrize("suffix", [".h5", ".npz"])
def test_bad_domain_is_one_line(recording, tmp_path: Path, case: str, suffix: str) -> None:
    kwargs, expected = DOMAIN_BAD[case]
    path = _h5(tmp_path / "bad.h5", recording, **kwargs)
    if suffix == ".npz":  # the same attributes as .npz members
        with h5py.File(path) as f:
            arrays = {k: np.asarray(v) for k, v in f.attrs.items()}
            arrays["iq"] = f["iq"][()]
        path = tmp_path / "bad.npz"
        np.savez(path, **arrays)
    with pytest.raises(RecordingError, match=expected.replace("(", r"\(")) as err:
        read_recording(path)
    assert "\n" not in str(err.value)


def test_writer_refuses_an_unknown_domain(recording, tmp_path: Path) -> None:
    rec = recording.__class__(recording.config, recording.site, recording.start_time, recording.iq, domain="x")
    with pytest.raises(RecordingError, match="domain"):
        write_recording(rec, tmp_path / "x.h5")
    assert not (tmp_path / "x.h5").exists()


def test_each_attribute_is_opened_once_and_read_as_h5py_reads_it(recording, tmp_path: Path, monkeypatch) -> None:
    """An HDF5 read opens each of the format's attributes once, strings included (no second open by
    name through h5py's attribute manager), and gets the value and type h5py's `attrs[name]` gives:
    variable-length strings (non-ASCII too), float64s, and any other type (through h5py)."""
    from h5py import h5a

    from signatures.recording import _ATTR_NAMES, _h5_attrs

    path = write_recording(recording, tmp_path / "r.h5")
    with h5py.File(path, "a") as f:
        f.attrs["simulation"] = '{"note": "été"}'
    opened: list[bytes] = []
    real = h5a.open

    def counted(loc, name=None, *args, **kwargs):
        opened.append(name)
        return real(loc, name, *args, **kwargs)

    monkeypatch.setattr(h5a, "open", counted)
    rec = read_recording(path)
    monkeypatch.undo()
    assert sorted(opened) == sorted(n.encode() for n in _ATTR_NAMES)  # each tried once (an absent one fails)
    assert rec.simulation == '{"note": "été"}'
    with h5py.File(path, "a") as f:
        f.attrs["remote_id_source"] = np.bytes_(b"capture")  # fixed-length: h5py's own reading
        f.attrs["radar_alt_m"] = np.float32(12.5)
        expected = {k: f.attrs[k] for k in f.attrs}
    with h5py.File(path) as f:
        got = _h5_attrs(f)
    assert got == expected and {k: type(v) for k, v in got.items()} == {k: type(v) for k, v in expected.items()}
    assert isinstance(got["format"], str) and isinstance(got["start_time"], str)


def test_an_hdf5_read_imports_no_zipfile(recording, tmp_path: Path) -> None:
    """zipfile (an .npz read's) is imported by an .npz read only: reading HDF5 in a fresh process
    leaves it out."""
    import subprocess
    import sys

    path = write_recording(recording, tmp_path / "r.h5")
    probe = ("import sys; from signatures.recording import read_recording; "
             f"read_recording({str(path)!r}); print('zipfile' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=120,
                         cwd=Path(__file__).resolve().parents[1])
    assert out.stdout.strip() == "False", out.stderr
