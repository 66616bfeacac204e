"""A recorded return's HDF5 attributes are read into one dict once per file, each from the one id
it is opened by (never again by name through h5py's `attrs[name]`), giving exactly what
`attrs[name]` gives for every kind the format stores."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import _ATTR_NAMES, _h5_attrs, read_recording, write_recording
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate

#: other stored kinds of a format number: each must read as h5py reads it
STORED = {"big-endian": np.array(1.5e9, dtype=">f8"), "float32": np.float32(0.25), "integer": np.int64(7),
          "array": np.array([3.0]), "text": "2.0"}


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    scene = Scene(profile=shipped_profiles()["m300"], range_m=300.0, radial_speed_mps=2.0, snr_db=20.0)
    rec, _ = simulate(scene, get_preset("paper"), seed=1)
    return write_recording(rec, tmp_path_factory.mktemp("a") / "r.h5")


def _h5py_view(f: h5py.File) -> dict:
    return {n: f.attrs[n] for n in _ATTR_NAMES if n in f.attrs}


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(type(a[k]) is type(b[k]) and np.array_equal(a[k], b[k]) for k in a)


def test_no_attribute_goes_through_h5py_dispatch(written: Path, monkeypatch) -> None:
    """Each attribute is read from the one id the reader opens it by: none through h5py's
    `attrs[name]`, which would open it again by name (text ones included)."""
    calls: list[str] = []
    real = h5py.AttributeManager.__getitem__

    def counted(self, name):
        calls.append(name)
        return real(self, name)

    monkeypatch.setattr(h5py.AttributeManager, "__getitem__", counted)
    assert read_recording(written).config is not None
    assert calls == []


@pytest.mark.parametrize("kind", sorted(STORED))
def test_every_stored_kind_reads_as_h5py_reads_it(written: Path, tmp_path: Path, kind: str) -> None:
    path = tmp_path / "r.h5"
    path.write_bytes(written.read_bytes())
    with h5py.File(path, "a") as f:
        del f.attrs["carrier_hz"]
        f.attrs["carrier_hz"] = STORED[kind]
    with h5py.File(path, "r") as f:
        assert _same(_h5_attrs(f), _h5py_view(f))


def test_untouched_file_reads_as_h5py_reads_it(written: Path) -> None:
    with h5py.File(written, "r") as f:
        assert _same(_h5_attrs(f), _h5py_view(f))
