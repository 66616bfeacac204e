"""Regression corpus of malformed and edge-case recorded returns (deterministic, seeded).

`build_corpus(directory)` writes 500-odd files derived from one valid simulated
recording (paper preset, with Remote ID rows) and returns a `Case` per file:
its class (what kind of damage), and what the reader must do with it:

- "valid": a Recording comes back (the CLI then decides it: exit 0 or 1);
- "bad":   RecordingError with a one-line message (the CLI exits 2);
- "either": random damage (bit flips) whose effect is not known in advance; the
  file is accepted or refused, but nothing else may happen.

Run `python -m tests.fuzz.corpus DIR` to write the corpus somewhere and list it.
"""

from __future__ import annotations

import io
import os
import random
import struct
import sys
import warnings
import zipfile
from dataclasses import dataclass, replace
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Callable

import h5py
import numpy as np

SEED = 20261123
SERIAL = "1581F0000000000001"
VALID, BAD, EITHER = "valid", "bad", "either"

NUMERIC_ATTRS = ("carrier_hz", "bandwidth_hz", "ramp_s", "pri_s", "sample_rate_hz", "range_offset_m",
                 "radar_lat_deg", "radar_lon_deg", "radar_alt_m")
REQUIRED_ATTRS = ("format", "carrier_hz", "bandwidth_hz", "ramp_s", "pri_s", "sample_rate_hz",
                  "radar_lat_deg", "radar_lon_deg", "radar_alt_m", "start_time")


@dataclass(frozen=True)
class Case:
    name: str  # unique, also the file name stem
    cls: str  # damage class, e.g. "attr_type", "bitflip", "npz_encrypted"
    expect: str  # VALID, BAD or EITHER
    path: Path


def base_recording():
    """The valid recording every case starts from (simulated once, deterministic)."""
    from authn.scenario import Broadcast, simulate_flight
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.sim.scene import Scene

    scene = Scene(profile=shipped_profiles()["m300"], range_m=300.0, radial_speed_mps=3.0, snr_db=10.0)
    rec, _ = simulate_flight(scene, get_preset("paper"), 7, Broadcast(serial=SERIAL))
    return rec


def _opaque(n: int = 4) -> np.ndarray:
    return np.frombuffer(b"\x01\x02\x03\x04"[:n], dtype=f"V{n}")


class _Builder:
    def __init__(self, directory: Path, rec) -> None:
        from signatures.recording import write_recording

        self.dir = directory
        self.rec = rec
        self.cases: list[Case] = []
        self.rng = random.Random(SEED)
        self.base_h5 = write_recording(rec, directory / "_base.h5")
        self.base_npz = write_recording(rec, directory / "_base.npz")
        mini = replace(rec, iq=np.ascontiguousarray(rec.iq[:32, :16]))
        self.mini_h5 = write_recording(mini, directory / "_mini.h5")
        self.mini_npz = write_recording(mini, directory / "_mini.npz")
        self.other_h5 = write_recording(rec, directory / "_other.h5")  # target of external links

    # --- helpers ------------------------------------------------------------------
    def add(self, cls: str, expect: str, name: str, path: Path) -> None:
        self.cases.append(Case(name, cls, expect, path))

    def h5(self, cls: str, expect: str, name: str, edit: Callable[[h5py.File], None],
           base: Path | None = None) -> None:
        path = self.dir / f"{name}.h5"
        path.write_bytes((base or self.base_h5).read_bytes())
        with h5py.File(path, "a") as f:
            edit(f)
        self.add(cls, expect, name, path)

    def raw(self, cls: str, expect: str, name: str, data: bytes, suffix: str = ".h5") -> None:
        path = self.dir / f"{name}{suffix}"
        path.write_bytes(data)
        self.add(cls, expect, name, path)

    def npz(self, cls: str, expect: str, name: str, arrays: dict[str, object]) -> None:
        path = self.dir / f"{name}.npz"
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        path.write_bytes(buf.getvalue())
        self.add(cls, expect, name, path)

    def base_arrays(self) -> dict[str, object]:
        with np.load(self.base_npz) as d:
            return {k: d[k] for k in d.files}


def _set_attr(name: str, value) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        if name in f.attrs:
            del f.attrs[name]
        f.attrs[name] = value
    return edit


def _set_attr_typed(name: str, data, dtype) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        if name in f.attrs:
            del f.attrs[name]
        f.attrs.create(name, data=data, dtype=dtype)
    return edit


def _replace_ds(name: str, **kw) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        if name in f:
            del f[name]
        f.create_dataset(name, **kw)
    return edit


def _attribute_cases(b: _Builder) -> None:
    for name in REQUIRED_ATTRS:
        b.h5("attr_missing", BAD, f"attr_missing_{name}", lambda f, n=name: f.attrs.__delitem__(n))
    b.h5("attr_missing", VALID, "attr_missing_range_offset_m", lambda f: f.attrs.__delitem__("range_offset_m"))
    b.h5("attr_missing", VALID, "attr_missing_simulation", lambda f: f.attrs.__delitem__("simulation"))

    extras = {
        "string": "hello", "int": 7, "array": np.arange(5.0), "complex": 1 + 2j, "nan": np.nan,
        "opaque": _opaque(), "empty": h5py.Empty("f8"), "bytes": np.bytes_(b"\xff\xfe"),
        "compound": np.array((1, 2.0), dtype=[("a", "i4"), ("b", "f8")]),
    }
    for kind, value in extras.items():
        b.h5("attr_extra", VALID, f"attr_extra_{kind}", _set_attr(f"extra_{kind}", value))
    b.h5("attr_extra", VALID, "attr_extra_many",
         lambda f: [f.attrs.__setitem__(f"x{i}", i) for i in range(40)])

    bad_values = {
        "string": "77 GHz", "numeric_string": "1.5", "array": np.array([1.0, 2.0]), "bool": True,
        "complex": 7.7e10 + 1e3j, "complex_zero_imag": np.complex128(1.0 + 0j), "nan": np.nan,
        "inf": np.inf, "neg_inf": -np.inf, "huge": 1e308, "int64_max": np.int64(2**63 - 1),
        "opaque": _opaque(), "empty": h5py.Empty("f8"),
        "compound": np.array((1, 2.0), dtype=[("a", "i4"), ("b", "f8")]),
        "negative": -1.0, "bytes": np.bytes_(b"\x80\x81"),
    }
    for attr in NUMERIC_ATTRS:
        for kind, value in bad_values.items():
            if attr == "range_offset_m" and kind == "negative":
                continue
            if attr in ("radar_lon_deg", "radar_lat_deg", "radar_alt_m") and kind == "negative":
                continue  # negative latitude/longitude/altitude are fine
            b.h5("attr_type", BAD, f"attr_type_{attr}_{kind}", _set_attr(attr, value))
    with h5py.File(b.base_h5, "r") as f:
        values = {a: float(f.attrs[a]) for a in NUMERIC_ATTRS}
    for attr, v in values.items():
        b.h5("attr_valid_variant", VALID, f"attr_bigendian_{attr}", _set_attr_typed(attr, v, ">f8"))
        b.h5("attr_valid_variant", VALID, f"attr_one_elem_array_{attr}", _set_attr(attr, np.array([v])))
        if attr not in ("pri_s", "ramp_s"):  # float32 rounding may put pri_s below ramp_s
            b.h5("attr_valid_variant", VALID, f"attr_float32_{attr}", _set_attr_typed(attr, v, "<f4"))
    b.h5("attr_valid_variant", VALID, "attr_int_carrier", _set_attr("carrier_hz", np.int64(77_000_000_000)))
    b.h5("attr_valid_variant", VALID, "attr_uint_range_offset", _set_attr("range_offset_m", np.uint16(0)))

    b.h5("attr_format", BAD, "attr_format_wrong", _set_attr("format", "uav-radar-return/9"))
    b.h5("attr_format", BAD, "attr_format_int", _set_attr("format", 1))
    b.h5("attr_format", BAD, "attr_format_array", _set_attr("format", np.array([b"uav-radar-return/1"] * 2)))
    b.h5("attr_format", VALID, "attr_format_fixed_bytes", _set_attr("format", np.bytes_(b"uav-radar-return/1")))
    b.h5("attr_format", BAD, "attr_format_opaque", _set_attr("format", _opaque()))

    now = datetime.now(timezone.utc)
    starts = {
        "year_9999": ("9999-12-31T23:59:59+00:00", BAD),
        "year_9999_neg_offset": ("9999-12-31T23:59:59-05:00", BAD),
        "year_1": ("0001-01-01T00:00:00+00:00", BAD),
        "year_1_pos_offset": ("0001-01-01T00:00:00+05:00", BAD),
        "year_1999": ("1999-12-31T23:59:59+00:00", BAD),
        "year_2100": ("2100-01-01T00:00:00+00:00", BAD),
        "future_1h": ((now + timedelta(hours=1)).isoformat(), BAD),
        "no_offset": ("2026-01-01T12:00:00", BAD),
        "not_iso": ("yesterday", BAD),
        "empty": ("", BAD),
        "newline": ("2026-01-01\nT12:00:00+00:00", BAD),
        "offset_24h": ("2026-01-01T12:00:00+24:00", BAD),
        "year_2000": ("2000-01-01T00:00:00+00:00", VALID),
        "zulu": ("2026-01-01T12:00:00Z", VALID),
        "plus_two": ("2026-01-01T14:00:00+02:00", VALID),
        "now_minus_1min": ((now - timedelta(minutes=1)).isoformat(), VALID),
        "now_plus_1min": ((now + timedelta(minutes=1)).isoformat(), VALID),
    }
    for kind, (value, expect) in starts.items():
        b.h5("start_time", expect, f"start_time_{kind}", _set_attr("start_time", value))
    b.h5("start_time", BAD, "start_time_nul", _set_attr("start_time", np.bytes_(b"2026-01-01\x00T12:00:00Z")))
    b.h5("start_time", BAD, "start_time_int", _set_attr("start_time", 1_700_000_000))
    b.h5("start_time", BAD, "start_time_array", _set_attr("start_time", np.array([b"2026-01-01T12:00:00Z"] * 2)))
    b.h5("start_time", VALID, "start_time_fixed_bytes", _set_attr("start_time", np.bytes_(b"2026-01-01T12:00:00Z")))
    b.h5("start_time", BAD, "start_time_invalid_utf8", _set_attr("start_time", np.bytes_(b"\xff\xfe2026")))

    b.h5("attr_simulation", BAD, "simulation_int", _set_attr("simulation", 3))
    b.h5("attr_simulation", BAD, "simulation_array", _set_attr("simulation", np.array(["{}", "{}"], dtype=object)))
    b.h5("attr_simulation", VALID, "simulation_bytes", _set_attr("simulation", np.bytes_(b"{}")))
    b.h5("attr_simulation", BAD, "simulation_opaque", _set_attr("simulation", _opaque()))
    b.h5("attr_simulation", BAD, "simulation_not_json", _set_attr("simulation", '{"scene": '))
    b.h5("attr_simulation", BAD, "simulation_deep_nesting", _set_attr("simulation", "[" * 100_000))


def _iq_cases(b: _Builder) -> None:
    iq = b.rec.iq
    b.h5("iq_missing", BAD, "iq_missing", lambda f: f.__delitem__("iq"))
    b.h5("iq_group", BAD, "iq_group", lambda f: (f.__delitem__("iq"), f.create_group("iq")))

    def named_type(f):
        del f["iq"]
        f["iq"] = np.dtype("c8")  # a committed datatype where the dataset belongs
    b.h5("iq_group", BAD, "iq_named_datatype", named_type)

    def soft(f):
        f.move("iq", "iq_data")
        f["iq"] = h5py.SoftLink("/iq_data")
    b.h5("iq_link", BAD, "iq_soft_link", soft)
    b.h5("iq_link", BAD, "iq_soft_link_dangling",
         lambda f: (f.__delitem__("iq"), f.__setitem__("iq", h5py.SoftLink("/nowhere"))))
    b.h5("iq_link", BAD, "iq_external_link",
         lambda f: (f.__delitem__("iq"), f.__setitem__("iq", h5py.ExternalLink(str(b.other_h5), "/iq"))))
    b.h5("iq_link", BAD, "iq_external_link_dangling",
         lambda f: (f.__delitem__("iq"), f.__setitem__("iq", h5py.ExternalLink(str(b.dir / "missing.h5"), "/iq"))))
    b.h5("iq_link", BAD, "iq_external_link_self",
         lambda f: (f.__delitem__("iq"), f.__setitem__("iq", h5py.ExternalLink(".", "/iq"))))

    raw = b.dir / "_external_raw.bin"
    raw.write_bytes(iq.tobytes())
    b.h5("iq_external_storage", BAD, "iq_external_storage",
         _replace_ds("iq", shape=iq.shape, dtype=iq.dtype, external=[(str(raw), 0, iq.nbytes)]))
    b.h5("iq_external_storage", BAD, "iq_external_storage_missing",
         _replace_ds("iq", shape=iq.shape, dtype=iq.dtype, external=[(str(b.dir / "gone.bin"), 0, iq.nbytes)]))
    if hasattr(os, "mkfifo"):
        fifo = b.dir / "_iq_fifo"
        os.mkfifo(fifo)
        b.h5("iq_external_storage", BAD, "iq_external_storage_fifo",
             _replace_ds("iq", shape=iq.shape, dtype=iq.dtype, external=[(str(fifo), 0, iq.nbytes)]))

    def virtual(f):
        del f["iq"]
        layout = h5py.VirtualLayout(shape=iq.shape, dtype=iq.dtype)
        layout[:] = h5py.VirtualSource(str(b.other_h5), "iq", shape=iq.shape)
        f.create_virtual_dataset("iq", layout)
    b.h5("iq_virtual", BAD, "iq_virtual", virtual)

    def virtual_self(f):
        f.move("iq", "iq_data")
        layout = h5py.VirtualLayout(shape=iq.shape, dtype=iq.dtype)
        layout[:] = h5py.VirtualSource(".", "iq_data", shape=iq.shape)
        f.create_virtual_dataset("iq", layout)
    b.h5("iq_virtual", BAD, "iq_virtual_same_file", virtual_self)

    b.h5("iq_null", BAD, "iq_null_dataspace", _replace_ds("iq", data=h5py.Empty("c8")))
    b.h5("iq_shape", BAD, "iq_scalar", _replace_ds("iq", data=np.complex64(1 + 1j)))
    for shape in [(80,), (2, 3, 4), (0, 80), (600, 0), (1, 1, 1, 1)]:
        b.h5("iq_shape", BAD, "iq_shape_" + "x".join(map(str, shape)), _replace_ds("iq", shape=shape, dtype="c8"))
    b.h5("iq_shape", VALID, "iq_shape_1x1", _replace_ds("iq", data=np.ones((1, 1), np.complex64)))
    for dt in ["f4", "f8", "i2", "u1", "i8", "f2", "S8", "c8", "c16"]:
        expect = VALID if dt in ("c8", "c16") else BAD
        data = np.zeros(iq.shape, dt) if dt[0] == "S" else (iq if dt[0] == "c" else iq.real).astype(dt)
        b.h5("iq_dtype", expect, f"iq_dtype_{dt}", _replace_ds("iq", data=data))
    b.h5("iq_dtype", BAD, "iq_dtype_vlen_str",
         _replace_ds("iq", data=np.array([["a", "b"]], dtype=object), dtype=h5py.string_dtype()))
    b.h5("iq_dtype", BAD, "iq_dtype_compound_xy",
         _replace_ds("iq", data=np.zeros(iq.shape, dtype=[("x", "f4"), ("y", "f4")])))
    b.h5("iq_dtype", BAD, "iq_dtype_compound_3",
         _replace_ds("iq", data=np.zeros(iq.shape, dtype=[("r", "f4"), ("i", "f4"), ("k", "f4")])))
    b.h5("iq_dtype", BAD, "iq_dtype_opaque", _replace_ds("iq", data=np.zeros(iq.shape, dtype="V8")))
    b.h5("iq_dtype", BAD, "iq_dtype_enum",
         _replace_ds("iq", data=np.zeros(iq.shape, "u1"), dtype=h5py.enum_dtype({"a": 0, "b": 1}, basetype="u1")))
    b.h5("iq_dtype", BAD, "iq_dtype_vlen_float",
         _replace_ds("iq", shape=(2, 2), dtype=h5py.vlen_dtype(np.float32)))
    for dt in [">c8", ">c16"]:
        b.h5("iq_bigendian", VALID, f"iq_bigendian_{dt[1:]}", _replace_ds("iq", data=iq.astype(dt)))
    b.h5("iq_storage", VALID, "iq_chunked_gzip", _replace_ds("iq", data=iq, chunks=(60, 80), compression="gzip"))
    b.h5("iq_storage", VALID, "iq_chunked_lzf_shuffle_fletcher",
         _replace_ds("iq", data=iq, chunks=(100, 40), compression="lzf", shuffle=True, fletcher32=True))
    b.h5("iq_storage", VALID, "iq_compact",
         _replace_ds("iq", data=iq[:8, :16], ), )
    b.h5("iq_storage", VALID, "iq_chunked_unwritten", _replace_ds("iq", shape=iq.shape, dtype="c8", chunks=True))
    b.h5("iq_storage", VALID, "iq_resizable",
         _replace_ds("iq", data=iq, maxshape=(None, None), chunks=(64, 16)))
    bad_vals = iq.copy()
    bad_vals[3, 5] = np.nan
    b.h5("iq_values", BAD, "iq_nan", _replace_ds("iq", data=bad_vals))
    bad_vals = iq.copy()
    bad_vals[0, 0] = complex(0, np.inf)
    b.h5("iq_values", BAD, "iq_inf_imag", _replace_ds("iq", data=bad_vals))
    b.h5("iq_values", BAD, "iq_nan_bigendian", _replace_ds("iq", data=np.full((4, 8), np.nan, ">c16")))
    for shape in [(1 << 20, 1 << 16), (2**25 + 1, 1), (1 << 40, 1 << 20)]:
        b.h5("iq_huge", BAD, "iq_huge_" + "x".join(map(str, shape)),
             _replace_ds("iq", shape=shape, dtype="c8", chunks=(1, min(shape[1], 1024)),
                         maxshape=(None, None)))
    b.h5("iq_huge", BAD, "iq_huge_c16_over_bytes", _replace_ds("iq", shape=(2**14, 2**12), dtype="c16",
                                                              chunks=(1, 1024)))
    b.h5("extra_objects", VALID, "extra_group_and_dataset",
         lambda f: (f.create_group("calibration"), f.create_dataset("notes", data=np.arange(3))))
    b.h5("extra_objects", VALID, "extra_external_link",
         lambda f: f.__setitem__("elsewhere", h5py.ExternalLink(str(b.dir / "missing.h5"), "/x")))
    b.h5("extra_objects", VALID, "extra_soft_dangling",
         lambda f: f.__setitem__("dangling", h5py.SoftLink("/nowhere")))
    b.h5("extra_objects", VALID, "no_remote_id", lambda f: (f.__delitem__("remote_id"),
                                                           f.__delitem__("remote_id_time_s")))


def _rid_cases(b: _Builder) -> None:
    rid = b.rec.remote_id
    n = rid.shape[0]
    times = b.rec.remote_id_time_s
    (b.dir / "_rid_raw.bin").write_bytes(bytes(10_000))
    for name in ("remote_id", "remote_id_time_s"):
        b.h5("rid_group", BAD, f"{name}_group", lambda f, nm=name: (f.__delitem__(nm), f.create_group(nm)))
        b.h5("rid_link", BAD, f"{name}_soft_link",
             lambda f, nm=name: (f.move(nm, nm + "_data"), f.__setitem__(nm, h5py.SoftLink(f"/{nm}_data"))))
        b.h5("rid_link", BAD, f"{name}_external_link",
             lambda f, nm=name: (f.__delitem__(nm), f.__setitem__(nm, h5py.ExternalLink(str(b.other_h5), f"/{nm}"))))
        b.h5("rid_link", BAD, f"{name}_soft_dangling",
             lambda f, nm=name: (f.__delitem__(nm), f.__setitem__(nm, h5py.SoftLink("/nowhere"))))
        b.h5("rid_null", BAD, f"{name}_null_dataspace", _replace_ds(name, data=h5py.Empty("u1")))
        b.h5("rid_dtype", BAD, f"{name}_vlen_strings",
             _replace_ds(name, data=np.array(["x"] * n, dtype=object), dtype=h5py.string_dtype()))
        b.h5("rid_dtype", BAD, f"{name}_fixed_strings", _replace_ds(name, data=np.array([b"abc"] * n)))
        b.h5("rid_dtype", BAD, f"{name}_complex", _replace_ds(name, data=np.zeros(n, "c8")))
        b.h5("rid_dtype", BAD, f"{name}_opaque", _replace_ds(name, data=np.zeros(n, "V4")))
        b.h5("rid_storage", BAD, f"{name}_external_storage",
             _replace_ds(name, shape=(n, 25) if name == "remote_id" else (n,),
                         dtype="u1" if name == "remote_id" else "f8",
                         external=[(str(b.dir / "_rid_raw.bin"), 0, 10_000)]))
    for dt in ["i2", "f4", "u2", "i1", "S25"]:
        b.h5("rid_dtype", BAD, f"remote_id_dtype_{dt}", _replace_ds("remote_id", data=rid.astype(dt)))
    for shape in [(n, 24), (n * 25,), (n, 25, 1), (100_001, 25), (1 << 40, 25)]:
        kw = {"chunks": True, "maxshape": (None,) * len(shape)} if shape[0] > 100_000 else {}
        b.h5("rid_shape", BAD, "remote_id_shape_" + "x".join(map(str, shape)),
             _replace_ds("remote_id", shape=shape, dtype="u1", **kw))
    b.h5("rid_valid_variant", VALID, "remote_id_empty",
         lambda f: (_replace_ds("remote_id", shape=(0, 25), dtype="u1")(f),
                    _replace_ds("remote_id_time_s", shape=(0,), dtype="f8")(f)))
    b.h5("rid_valid_variant", VALID, "remote_id_without_times", lambda f: f.__delitem__("remote_id_time_s"))
    b.h5("rid_shape", BAD, "times_without_remote_id", lambda f: f.__delitem__("remote_id"))
    for dt in [">f8", "<f4", ">i4", "u2", "<f2"]:
        b.h5("rid_valid_variant", VALID, f"times_dtype_{dt.strip('<>')}_{'be' if dt[0] == '>' else 'le'}",
             _replace_ds("remote_id_time_s", data=times.astype(dt) if dt[1] == "f" else np.arange(n).astype(dt)))
    b.h5("rid_dtype", BAD, "times_bool", _replace_ds("remote_id_time_s", data=np.ones(n, bool)))
    for shape in [(n + 1,), (n, 1), (), (1 << 30,)]:
        kw = {"chunks": True, "maxshape": (None,)} if shape and shape[0] > 100_000 else {}
        b.h5("rid_shape", BAD, "times_shape_" + ("x".join(map(str, shape)) or "scalar"),
             _replace_ds("remote_id_time_s", shape=shape, dtype="f8", **kw))
    bad_t = times.astype("f8")
    bad_t[0] = np.nan
    b.h5("rid_values", BAD, "times_nan", _replace_ds("remote_id_time_s", data=bad_t))
    b.h5("rid_values", BAD, "times_inf_bigendian", _replace_ds("remote_id_time_s", data=np.full(n, np.inf, ">f8")))


def _truncation_cases(b: _Builder) -> None:
    for base, suffix in ((b.base_h5, ".h5"), (b.base_npz, ".npz")):
        data = base.read_bytes()
        size = len(data)
        offsets = {0, 1, 4, 7, 8, 9, 16, 48, 96, 100, 200, 512, 1000, 1500, 2048, 3000, 4096, 6000, 8192,
                   size // 4, size // 3, size // 2, size - 4096, size - 2048, size - 512, size - 100,
                   size - 22, size - 21, size - 8, size - 1}
        offsets |= {b.rng.randrange(1, size) for _ in range(14)}
        for off in sorted(o for o in offsets if 0 <= o < size):
            b.raw("truncation", BAD, f"trunc{suffix[1:]}_{off:07d}", data[:off], suffix)
    for suffix, base in ((".h5", b.base_h5), (".npz", b.base_npz)):
        b.raw("trailing_garbage", VALID if suffix == ".h5" else EITHER, f"trailing_garbage_{suffix[1:]}",
              base.read_bytes() + bytes(range(256)) * 4, suffix)


def _flip(data: bytes, rng: random.Random, lo: int, hi: int, n: int = 1) -> bytes:
    out = bytearray(data)
    for _ in range(n):
        i = rng.randrange(lo, hi)
        out[i] ^= 1 << rng.randrange(8)
    return bytes(out)


def _bitflip_cases(b: _Builder) -> None:
    """Random bit flips in the metadata of a small file (flips in IQ samples only change
    numbers): >= 150 HDF5 flips, flips targeted at each attribute and link, .npz flips."""
    data = b.mini_h5.read_bytes()
    with h5py.File(b.mini_h5, "r") as f:
        iq_off, iq_len = f["iq"].id.get_offset(), f["iq"].id.get_storage_size()
    meta = [i for i in range(len(data)) if not iq_off <= i < iq_off + iq_len]
    for k in range(170):
        out = bytearray(data)
        for _ in range(1 + k % 3):
            i = meta[b.rng.randrange(len(meta))]
            out[i] ^= 1 << b.rng.randrange(8)
        b.raw("bitflip", EITHER, f"bitflip_h5_{k:03d}", bytes(out))
    for word in [n.encode() for n in (*REQUIRED_ATTRS, "range_offset_m", "simulation")] + [b"iq", b"remote_id"]:
        pos = data.find(word)
        while pos >= 0 and pos < 8:
            pos = data.find(word, pos + 1)
        if pos < 0:
            continue
        for j in range(3):
            lo = max(0, pos - 24)
            out = _flip(data, b.rng, lo, pos + len(word), 1 + j)
            b.raw("bitflip_meta", EITHER, f"bitflip_meta_{word.decode()}_{j}", out)
    npz = b.mini_npz.read_bytes()
    for k in range(40):
        # local headers and .npy headers sit at the start of each member; the central directory at the end
        lo, hi = (0, min(len(npz), 400)) if k % 2 == 0 else (max(0, len(npz) - 1500), len(npz))
        b.raw("bitflip_npz", EITHER, f"bitflip_npz_{k:03d}", _flip(npz, b.rng, lo, hi, 1 + k % 2), ".npz")


def _zip_patch(data: bytes, member: str, *, flag: int | None = None, method: int | None = None) -> bytes:
    """Set a general-purpose flag bit or the compression method of one member, in both its
    local header and its central directory entry."""
    out = bytearray(data)
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        info = zf.getinfo(member)
    lh = info.header_offset
    if flag is not None:
        struct.pack_into("<H", out, lh + 6, struct.unpack_from("<H", out, lh + 6)[0] | flag)
    if method is not None:
        struct.pack_into("<H", out, lh + 8, method)
    cd = out.find(b"PK\x01\x02")
    while cd >= 0:
        name_len = struct.unpack_from("<H", out, cd + 28)[0]
        if out[cd + 46:cd + 46 + name_len] == member.encode():
            if flag is not None:
                struct.pack_into("<H", out, cd + 8, struct.unpack_from("<H", out, cd + 8)[0] | flag)
            if method is not None:
                struct.pack_into("<H", out, cd + 10, method)
            break
        cd = out.find(b"PK\x01\x02", cd + 4)
    return bytes(out)


def _npz_cases(b: _Builder) -> None:
    base = b.base_arrays()
    data = b.base_npz.read_bytes()
    b.npz("npz_member", BAD, "npz_missing_iq", {k: v for k, v in base.items() if k != "iq"})
    b.npz("npz_member", BAD, "npz_missing_carrier", {k: v for k, v in base.items() if k != "carrier_hz"})
    b.npz("npz_member", VALID, "npz_extra_member", {**base, "notes": np.arange(4)})
    b.npz("npz_member", BAD, "npz_iq_object", {**base, "iq": np.array([[object()]], dtype=object)})
    b.npz("npz_member", BAD, "npz_attr_object", {**base, "carrier_hz": np.array([{"x": 1}], dtype=object)})
    b.npz("npz_member", BAD, "npz_rid_object", {**base, "remote_id": np.array([[None] * 25], dtype=object)})
    b.npz("npz_member", BAD, "npz_iq_float", {**base, "iq": base["iq"].real.copy()})
    b.npz("npz_member", BAD, "npz_carrier_complex", {**base, "carrier_hz": np.complex128(7.7e10 + 5j)})
    b.npz("npz_member", BAD, "npz_carrier_string", {**base, "carrier_hz": np.array("77e9")})
    b.npz("npz_member", BAD, "npz_carrier_nan", {**base, "carrier_hz": np.array(np.nan)})
    b.npz("npz_member", BAD, "npz_start_9999", {**base, "start_time": np.array("9999-12-31T23:59:59+00:00")})
    b.npz("npz_member", BAD, "npz_start_0001", {**base, "start_time": np.array("0001-01-01T00:00:00+00:00")})
    b.npz("npz_member", BAD, "npz_times_strings",
          {**base, "remote_id_time_s": np.array(["a"] * len(base["remote_id"]))})
    b.npz("npz_member", BAD, "npz_rid_float", {**base, "remote_id": base["remote_id"].astype("f4")})
    b.npz("npz_member", BAD, "npz_attr_huge_array", {**base, "simulation": np.zeros(300_000)})
    b.npz("npz_bigendian", VALID, "npz_iq_bigendian_c8", {**base, "iq": base["iq"].astype(">c8")})
    b.npz("npz_bigendian", VALID, "npz_iq_bigendian_c16", {**base, "iq": base["iq"].astype(">c16")})
    b.npz("npz_bigendian", VALID, "npz_times_bigendian",
          {**base, "remote_id_time_s": base["remote_id_time_s"].astype(">f8")})
    b.npz("npz_bigendian", VALID, "npz_carrier_bigendian", {**base, "carrier_hz": np.array(base["carrier_hz"], ">f8")})
    b.npz("npz_layout", VALID, "npz_iq_fortran", {**base, "iq": np.asfortranarray(base["iq"])})
    path = b.dir / "npz_compressed.npz"
    np.savez_compressed(path, **base)
    b.add("npz_layout", VALID, "npz_compressed", path)

    # headers that lie: shapes far larger than the data, an unknown .npy version
    def patched_member(name: str, old: bytes, new: bytes) -> bytes:
        buf = io.BytesIO()
        with zipfile.ZipFile(io.BytesIO(data)) as src, zipfile.ZipFile(buf, "w") as dst:
            for info in src.infolist():
                blob = src.read(info)
                if info.filename == name:
                    assert old in blob, (name, blob[:128])
                    blob = blob.replace(old, new, 1)
                dst.writestr(info, blob)
        return buf.getvalue()

    n_chirps, n_samples = base["iq"].shape
    shape_txt = f"({n_chirps}, {n_samples})".encode()
    for k, new in enumerate([b"(1099511627776, 1048576)", b"(99999999, 80)", b"(600, 81)", b"(600,)", b"()"]):
        b.raw("npz_header", BAD, f"npz_iq_header_shape_{k}",
              patched_member("iq.npy", shape_txt, new.ljust(len(shape_txt))), ".npz")
    b.raw("npz_header", BAD, "npz_iq_header_dtype",
          patched_member("iq.npy", b"'<c8'", b"'|O8'"), ".npz")
    b.raw("npz_header", BAD, "npz_iq_npy_version_9",
          patched_member("iq.npy", b"\x93NUMPY\x01", b"\x93NUMPY\x09"), ".npz")
    b.raw("npz_header", BAD, "npz_attr_header_huge",
          patched_member("carrier_hz.npy", b"'shape': ()", b"'shape': (1099511627776,)"), ".npz")
    b.raw("npz_header", BAD, "npz_iq_header_garbage",
          patched_member("iq.npy", b"'descr'", b"'d\x00scr'"), ".npz")

    for member in ("iq.npy", "carrier_hz.npy", "remote_id.npy"):
        stem = member.removesuffix(".npy")
        b.raw("npz_encrypted", BAD, f"npz_encrypted_{stem}", _zip_patch(data, member, flag=0x1), ".npz")
        for method in (99, 6, 97):
            b.raw("npz_compression", BAD, f"npz_method{method}_{stem}", _zip_patch(data, member, method=method), ".npz")
        b.raw("npz_compression", BAD, f"npz_deflate_claimed_{stem}", _zip_patch(data, member, method=8), ".npz")
    b.raw("npz_truncated", BAD, "npz_pk_only", b"PK\x03\x04", ".npz")
    b.raw("npz_truncated", BAD, "npz_pk_garbage", b"PK" + bytes(range(256)) * 8, ".npz")
    b.raw("npz_truncated", BAD, "npz_empty_zip", _empty_zip(), ".npz")

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for k, v in base.items():
            arr = io.BytesIO()
            np.save(arr, v)
            zf.writestr(f"{k}.npy", arr.getvalue())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            zf.writestr("iq.npy", b"not an array")  # a duplicate name: zipfile reads the last one
    b.raw("npz_member", BAD, "npz_duplicate_member", buf.getvalue(), ".npz")


def _empty_zip() -> bytes:
    buf = io.BytesIO()
    zipfile.ZipFile(buf, "w").close()
    return buf.getvalue()


def _special_cases(b: _Builder) -> None:
    if hasattr(os, "mkfifo"):
        fifo = b.dir / "fifo.h5"
        os.mkfifo(fifo)
        b.add("special_file", BAD, "fifo_h5", fifo)
        fifo_npz = b.dir / "fifo.npz"
        os.mkfifo(fifo_npz)
        b.add("special_file", BAD, "fifo_npz", fifo_npz)
    d = b.dir / "directory.h5"
    d.mkdir()
    b.add("special_file", BAD, "directory_h5", d)
    b.add("special_file", BAD, "missing_file", b.dir / "does_not_exist.h5")
    if os.path.exists(os.devnull) and os.name == "posix":
        b.add("special_file", BAD, "dev_null", Path(os.devnull))
    link = b.dir / "symlink_to_valid.h5"
    link.symlink_to(b.base_h5)
    b.add("special_file", VALID, "symlink_to_valid", link)
    link = b.dir / "symlink_to_fifo.h5"
    if hasattr(os, "mkfifo"):
        link.symlink_to(b.dir / "fifo.h5")
        b.add("special_file", BAD, "symlink_to_fifo", link)
    b.raw("special_file", BAD, "empty_h5", b"")
    b.raw("special_file", BAD, "empty_npz", b"", ".npz")
    b.raw("special_file", BAD, "not_a_recording", b"hello world\n", ".bin")
    big = b.dir / "oversize.h5"
    with big.open("wb") as fh:  # sparse: 1 GiB + 1 byte declared, a few bytes on disk
        fh.write(b"\x89HDF\r\n\x1a\n")
        fh.truncate(2**30 + 1)
    b.add("special_file", BAD, "oversize_file", big)


def build_corpus(directory: Path, rec=None) -> list[Case]:
    """Write the corpus into `directory` (created) and return its cases, in a fixed order."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    b = _Builder(directory, rec if rec is not None else base_recording())
    b.add("baseline", VALID, "baseline_h5", b.base_h5)
    b.add("baseline", VALID, "baseline_npz", b.base_npz)
    b.add("baseline", VALID, "baseline_mini_h5", b.mini_h5)
    _attribute_cases(b)
    _iq_cases(b)
    _rid_cases(b)
    _truncation_cases(b)
    _bitflip_cases(b)
    _npz_cases(b)
    _special_cases(b)
    names = [c.name for c in b.cases]
    assert len(names) == len(set(names)), "case names must be unique"
    return b.cases


if __name__ == "__main__":
    from collections import Counter

    out = Path(sys.argv[1] if len(sys.argv) > 1 else "fuzz-corpus")
    cases = build_corpus(out)
    for c in cases:
        print(f"{c.expect:6} {c.cls:22} {c.name}")
    print(f"{len(cases)} cases in {out}: {dict(Counter(c.expect for c in cases))}")
