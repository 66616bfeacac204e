"""Structure-aware property test of the reader: hypothesis builds HDF5 files from
strategies over attributes (names, types, values incl. complex/NaN/huge), dataset
dtypes, byte orders, shapes, storage and links, then optionally truncates them or
flips bits. The reader must return a valid Recording or raise a one-line
RecordingError; where every choice is known-good (or one is known-bad) the outcome
must match.

AUTHN_FUZZ_EXAMPLES raises the number of examples (CI default 60; nightly: 10000).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from signatures.recording import FORMAT_TAG
from tests.fuzz.helpers import CASE_SECONDS, is_one_line, read_in_child

EXAMPLES = int(os.environ.get("AUTHN_FUZZ_EXAMPLES", "60"))
NIGHTLY = EXAMPLES > 1000

GOOD_ATTRS: dict[str, Any] = {
    "format": FORMAT_TAG, "carrier_hz": 77e9, "bandwidth_hz": 150e6, "ramp_s": 50e-6, "pri_s": 100e-6,
    "sample_rate_hz": 2e6, "range_offset_m": 250.0, "radar_lat_deg": 52.0, "radar_lon_deg": 4.4,
    "radar_alt_m": 12.0, "start_time": "2026-01-01T12:00:00+00:00", "simulation": "{}",
}
NUMERIC = [k for k, v in GOOD_ATTRS.items() if isinstance(v, float)]
OPTIONAL = ("range_offset_m", "simulation")


@dataclass
class Plan:
    """What a drawn file contains, and what the reader must make of it."""

    attrs: dict[str, Any] = field(default_factory=dict)  # name -> (value, dtype or None)
    datasets: list[tuple[str, Any]] = field(default_factory=list)
    verdict: str = "valid"  # "valid", "bad" or "either"
    damage: tuple = ()

    def mark(self, what: str) -> None:
        order = {"valid": 0, "either": 1, "bad": 2}
        if order[what] > order[self.verdict]:
            self.verdict = what


# --- attribute values -------------------------------------------------------------------

finite = st.floats(allow_nan=False, allow_infinity=False)
texts = st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=30)
odd_numbers = st.one_of(
    st.just(np.nan), st.just(np.inf), st.just(-np.inf), st.just(1e308), st.just(-1e308),
    st.just(np.int64(2**63 - 1)), st.just(np.uint64(2**64 - 1)), st.just(np.int64(-(2**63))),
    st.complex_numbers(allow_nan=True, allow_infinity=True).filter(lambda z: z.imag != 0),
    st.booleans(), texts,
    st.binary(max_size=12).map(np.bytes_),
    st.lists(finite, min_size=0, max_size=4).map(lambda v: np.array(v)),
    st.just(h5py.Empty("f8")), st.just(np.frombuffer(b"\x00\x01\x02\x03", "V4")),
    st.just(np.array((1, 2.5), dtype=[("a", "<i4"), ("b", "<f8")])),
)


start_times = st.one_of(
    st.datetimes().map(lambda d: d.isoformat() + "+00:00"),
    st.datetimes().map(lambda d: d.isoformat()),  # no offset
    st.tuples(st.datetimes(), st.integers(-23 * 60, 23 * 60)).map(
        lambda t: t[0].isoformat() + f"{'+' if t[1] >= 0 else '-'}{abs(t[1]) // 60:02d}:{abs(t[1]) % 60:02d}"),
    texts,
    st.integers(-(2**63), 2**63 - 1).map(np.int64),
)


@st.composite
def attribute_plan(draw, plan: Plan, broken: bool) -> None:
    mutated = draw(st.sets(st.sampled_from(sorted(GOOD_ATTRS)), min_size=1, max_size=3)) if broken else set()
    for name, good in GOOD_ATTRS.items():
        choice = draw(st.sampled_from(["missing", "odd", "odd", "bigendian", "array1"])) if name in mutated else "good"
        if choice == "good":
            plan.attrs[name] = (good, None)
        elif choice == "missing":
            plan.mark("valid" if name in OPTIONAL else "bad")
        elif choice == "bigendian" and name in NUMERIC:
            plan.attrs[name] = (good, ">f8")
        elif choice == "array1" and name in NUMERIC:
            plan.attrs[name] = (np.array([good]), None)
        elif name == "start_time":
            plan.attrs[name] = (draw(start_times), None)
            plan.mark("either")
        elif name in NUMERIC:
            plan.attrs[name] = (draw(st.one_of(odd_numbers, finite)), None)
            plan.mark("either")
        else:
            plan.attrs[name] = (draw(odd_numbers), None)
            plan.mark("either")
    for _ in range(draw(st.integers(0, 3))):  # extra attributes are ignored, whatever they hold
        extra = draw(texts.filter(lambda s: s and "/" not in s and s not in GOOD_ATTRS and s != "."))
        plan.attrs[extra] = (draw(odd_numbers), None)


# --- datasets ---------------------------------------------------------------------------



@st.composite
def dataset_plan(draw, plan: Plan, broken: set[str]) -> None:
    def pick(part: str, good: list[str], bad: list[str]) -> str:
        return draw(st.sampled_from(good + bad if part in broken else good))

    # /iq
    kind = pick("iq", ["plain", "chunked", "gzip"], ["missing", "group", "soft", "external_link", "null",
                                                     "scalar", "nd"])
    dt = pick("iq", ["<c8", ">c8", "<c16", ">c16"], ["<f4", ">f8", "<i2", "u1"])
    shape = (draw(st.integers(1, 12)), draw(st.integers(1, 12)))
    if kind == "nd":
        shape = tuple(draw(st.lists(st.integers(0, 4), min_size=1, max_size=4)))
        plan.mark("either" if len(shape) == 2 else "bad")
        if len(shape) == 2 and 0 in shape:
            plan.mark("bad")
    if kind in ("missing", "group", "soft", "external_link", "null", "scalar"):
        plan.mark("bad")
    if dt[1] != "c":
        plan.mark("bad")
    nan = "iq" in broken and draw(st.booleans())
    if nan and dt[1] == "c":
        plan.mark("bad")
    plan.datasets.append(("iq", (kind, dt, shape, nan)))
    # /remote_id and /remote_id_time_s
    n = draw(st.integers(0, 5))
    rid_kind = pick("rid", ["none", "plain", "plain"], ["group", "soft", "wrong_width", "null"])
    rid_dt = pick("rid", ["u1"], ["i2", "<f4", "S4", "c8"])
    if rid_kind != "none":
        if rid_kind != "plain" or rid_dt != "u1":
            plan.mark("bad")
        plan.datasets.append(("remote_id", (rid_kind, rid_dt, (n, 25 if rid_kind != "wrong_width" else 24), False)))
    t_kind = "none" if rid_kind == "none" and "times" not in broken else pick(
        "times", ["none", "plain", "plain"], ["wrong_len", "group", "null"])
    t_dt = pick("times", ["<f8", ">f8", "<f4", ">i4", "u2"], ["c8", "?", "S4"])
    if t_kind != "none":
        if rid_kind == "none" or t_kind != "plain" or t_dt in ("c8", "?", "S4"):
            plan.mark("bad")
        plan.datasets.append(("remote_id_time_s", (t_kind, t_dt, (n + (t_kind == "wrong_len"),), False)))


def _values(dt: str, shape: tuple, rng: np.random.Generator) -> np.ndarray:
    dtype = np.dtype(dt)
    if dtype.kind == "c":
        return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)).astype(dtype)
    if dtype.kind == "S":
        return np.full(shape, b"ab", dtype)
    if dtype.kind == "b":
        return np.ones(shape, dtype)
    return (rng.random(shape) * 50).astype(dtype)


def _write(path: Path, plan: Plan, seed: int) -> None:
    rng = np.random.default_rng(seed)
    with h5py.File(path, "w") as f:
        for name, (value, dtype) in plan.attrs.items():
            if dtype is None:
                f.attrs[name] = value
            else:
                f.attrs.create(name, data=value, dtype=dtype)
        f.create_dataset("target", data=np.zeros(4, np.complex64))
        for name, (kind, dt, shape, nan) in plan.datasets:
            if kind == "missing":
                continue
            if kind == "group":
                f.create_group(name)
            elif kind == "soft":
                f[name] = h5py.SoftLink("/target")
            elif kind == "external_link":
                f[name] = h5py.ExternalLink(str(path.with_name("elsewhere.h5")), "/iq")
            elif kind == "null":
                f.create_dataset(name, data=h5py.Empty(dt))
            elif kind == "scalar":
                f.create_dataset(name, data=_values(dt, (), rng))
            else:
                data = _values(dt, shape, rng)
                if nan and data.dtype.kind == "c" and data.size:
                    data.flat[0] = np.nan
                kw: dict[str, Any] = {}
                if kind in ("chunked", "gzip") and data.size:
                    kw = {"chunks": True, "compression": "gzip" if kind == "gzip" else None}
                f.create_dataset(name, data=data, **kw)


@st.composite
def recorded_return(draw) -> tuple[Plan, int]:
    plan = Plan()
    broken = draw(st.sets(st.sampled_from(["attrs", "iq", "rid", "times", "file"]), max_size=2))
    draw(attribute_plan(plan, "attrs" in broken))
    draw(dataset_plan(plan, broken))
    damage = draw(st.sampled_from(["truncate", "flip", "flips"])) if "file" in broken else "none"
    if damage == "truncate":
        plan.damage = ("truncate", draw(st.floats(0.0, 0.999)))
        plan.mark("bad")
    elif damage != "none":
        plan.damage = ("flip", draw(st.integers(1, 1 if damage == "flip" else 8)), draw(st.integers(0, 2**32 - 1)))
        plan.mark("either")
    return plan, draw(st.integers(0, 2**32 - 1))


def _damage(path: Path, damage: tuple) -> None:
    if not damage:
        return
    data = bytearray(path.read_bytes())
    if damage[0] == "truncate":
        path.write_bytes(bytes(data[: int(len(data) * damage[1])]))
        return
    rng = np.random.default_rng(damage[2])
    for _ in range(damage[1]):
        i = int(rng.integers(len(data)))
        data[i] ^= 1 << int(rng.integers(8))
    path.write_bytes(bytes(data))


@pytest.fixture(scope="module")
def workdir():
    with tempfile.TemporaryDirectory(prefix="authn-fuzz-") as d:
        yield Path(d)


@settings(max_examples=EXAMPLES, deadline=None, database=None, derandomize=not NIGHTLY,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.function_scoped_fixture])
@given(drawn=recorded_return())
def test_reader_returns_a_recording_or_one_line_error(workdir: Path, drawn) -> None:
    plan, seed = drawn
    path = workdir / "case.h5"
    _write(path, plan, seed)
    _damage(path, plan.damage)
    got, msg = read_in_child(path, CASE_SECONDS)  # a child: a loop inside HDF5's C code is killable
    event(f"planned {plan.verdict}, read {got}")
    assert got in ("valid", "bad"), (got, msg, plan)
    if got == "bad":
        assert is_one_line(msg), msg
    if plan.verdict != "either":
        assert got == plan.verdict, (plan, msg)
