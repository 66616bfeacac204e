"""Recorded-return files (docs/format.md): HDF5 or .npz in, typed `Recording` out.

Reading validates everything before trusting it and checks the IQ shape before
loading it, so a hostile header cannot make us allocate an unbounded array.
Every failure of a read is a one-line `RecordingError` (exit code 2): only
regular files are opened, only data stored in the file itself are read (no
links, external storage or virtual datasets: the audit's file hash then covers
all the IQ and nothing can block on a FIFO), and any h5py / numpy / zipfile / OS
exception raised on the read path is converted.
"""

from __future__ import annotations

import io
import json
import math
import os
import stat
import struct
import zlib
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from core.checked import Checked, Invalid, number
from core.parsing import parse_iso_time
from signatures.errors import RecordingError
from signatures.radar import RadarConfig

if TYPE_CHECKING:
    import zipfile

FORMAT_TAG = "uav-radar-return/1"
#: The tag of files whose `domain` is not `if` (docs/format.md, "Versions"): a reader of
#: version 1 refuses them instead of reading range-compressed or CW samples as dechirped IF.
FORMAT_TAG_DOMAINS = "uav-radar-return/2"
#: What `/iq` holds (attribute `domain`): dechirped IF (chirps x fast-time samples, the
#: default), range-compressed slow time (pulses x range bins) or CW Doppler IQ (pulses x 1).
DOMAINS = ("if", "range", "cw")
RID_MESSAGE_BYTES = 25
#: Largest IQ cube read by default (2**25 cells = 256 MiB as complex64).
MAX_IQ_CELLS = 2**25
#: Largest IQ cube in bytes (the cell limit as complex128): checked from the header, before
#: anything is allocated, so a caller raising max_cells still has a memory bound.
MAX_IQ_BYTES = 2**29
#: Largest file opened at all (checked with stat before opening): bounds the work of a read.
MAX_FILE_BYTES = 2**30
#: Most Remote ID messages per recording (a dwell lasts seconds; 100 000 is generous).
MAX_RID_MESSAGES = 100_000
#: Largest |remote_id_time_s| (seconds from start_time): a capture's window is the dwell plus
#: at most an hour of clock skew, so a day is generous; beyond, the message time is nonsense
#: (and 1e15 s overflows Python's datetime).
MAX_RID_TIME_S = 86_400.0
#: Largest attribute member of an .npz (the `simulation` JSON is ~1 KB): bounds what a
#: hostile .npy header can make us allocate for a scalar.
MAX_NPZ_ATTR_BYTES = 2**20
#: Earliest accepted start_time. Nothing of this format predates it, and it keeps the
#: pipeline's datetime arithmetic far from year 1 (OverflowError).
EARLIEST_START = datetime(2000, 1, 1, tzinfo=timezone.utc)
#: How far past the reader's clock a start_time may lie (radar/host clock skew); later
#: dates are bad input, which also keeps year-9999 arithmetic from overflowing.
MAX_FUTURE_SKEW = timedelta(minutes=5)
#: The IQ element types (either byte order; converted to native on read).
IQ_DTYPES = (np.dtype(np.complex64), np.dtype(np.complex128))

_CONFIG_ATTRS = ("carrier_hz", "bandwidth_hz", "ramp_s", "pri_s", "sample_rate_hz")
_SITE_ATTRS = ("radar_lat_deg", "radar_lon_deg", "radar_alt_m")


@dataclass(frozen=True, kw_only=True)
class RadarSite(Checked):
    """WGS-84 position of the radar (checked on construction: `core.checked`)."""

    lat_deg: float = number(ge=-90, le=90)
    lon_deg: float = number(ge=-180, le=180)
    alt_m: float = number(ge=-1000, le=20000)


@dataclass(frozen=True, eq=False)
class Recording:
    """One dwell of one radar: configuration, site, time and the IQ cube."""

    config: RadarConfig
    site: RadarSite
    start_time: datetime
    iq: np.ndarray
    remote_id: np.ndarray | None = None
    remote_id_time_s: np.ndarray | None = None
    #: JSON of the simulated scene and its ground truth (attribute `simulation`); None for real data
    simulation: str | None = None
    #: what `iq` holds, one of DOMAINS (attribute `domain`; absent = "if")
    domain: str = "if"
    #: "capture": /remote_id came from a Remote ID capture and /remote_id_time_s is when the
    #: sniffer heard each message (attribute `remote_id_source`; docs/remoteid.md); None otherwise
    remote_id_source: str | None = None

    @property
    def n_chirps(self) -> int:
        return int(self.iq.shape[0])

    @property
    def mid_time(self) -> datetime:
        """Time of the middle of the dwell (Remote ID messages are matched to it)."""
        return self.start_time + timedelta(seconds=self.n_chirps * self.config.pri_s / 2)

    @property
    def n_samples(self) -> int:
        return int(self.iq.shape[1])


# --- validation shared by both containers ----------------------------------------


def _show(value: Any, limit: int = 60) -> str:
    """repr of a file's value for a one-line message: whitespace folded, length capped."""
    try:
        text = " ".join(repr(value).split())
    except Exception:  # noqa: BLE001  a hostile object's repr must not hide the real error
        text = f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _scalar(attrs: dict[str, Any], name: str) -> Any:
    if name not in attrs:
        raise RecordingError(f"missing attribute '{name}'")
    value = attrs[name]
    if isinstance(value, (np.ndarray, np.generic)) and value.dtype.kind == "V":
        raise RecordingError(f"attribute '{name}': opaque or compound type {value.dtype}")
    if isinstance(value, np.ndarray):
        if value.size != 1:
            raise RecordingError(f"attribute '{name}': expected a scalar, got shape {value.shape}")
        value = value.reshape(()).item()
    elif isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return value


def _float_attr(attrs: dict[str, Any], name: str, default: float | None = None) -> float:
    """A real, finite number. Complex values are refused (float() would drop the imaginary
    part silently), as are bools, strings and anything else."""
    if default is not None and name not in attrs:
        return default
    value = _scalar(attrs, name)
    if isinstance(value, (np.floating, np.integer)):  # float128 and the like: .item() keeps them
        value = value.item() if isinstance(value, np.integer) else float(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RecordingError(f"attribute '{name}': expected a real number, got {_show(value)}")
    try:
        value = float(value)
    except OverflowError:  # an integer beyond float range
        raise RecordingError(f"attribute '{name}': number out of range") from None
    if not math.isfinite(value):
        raise RecordingError(f"attribute '{name}': must be finite, got {value}")
    return value


def _config_error(exc: Invalid) -> RecordingError:
    """One line naming the attribute (the rule across fields is the pri_s >= ramp_s one)."""
    if not exc.loc:
        return RecordingError(f"attribute 'pri_s': {exc.msg}")
    return RecordingError(f"attribute '{exc.loc.split('.')[0]}': {exc.msg} (got {_show(exc.value)})")


def _start_time(attrs: dict[str, Any]) -> datetime:
    """ISO 8601 with an offset, between EARLIEST_START and now + MAX_FUTURE_SKEW (UTC out)."""
    start = _scalar(attrs, "start_time")
    if not isinstance(start, str):
        raise RecordingError(f"attribute 'start_time': expected an ISO 8601 string, got {_show(start)}")
    when = parse_iso_time(start, "attribute 'start_time'", error=RecordingError, naive_is_utc=False)
    try:
        when = when.astimezone(timezone.utc)
    except (OverflowError, ValueError):  # year 1 with a positive offset, year 9999 with a negative one
        when = None
    latest = datetime.now(timezone.utc) + MAX_FUTURE_SKEW
    if when is None or not EARLIEST_START <= when <= latest:
        raise RecordingError(f"attribute 'start_time': {_show(start)} is outside "
                             f"{EARLIEST_START:%Y-%m-%d} .. now + {MAX_FUTURE_SKEW.seconds // 60} min")
    return when


def _domain(attrs: dict[str, Any]) -> str:
    """The `domain` attribute (absent = "if"); version 1 files predate the other domains."""
    tag = _scalar(attrs, "format")
    if tag not in (FORMAT_TAG, FORMAT_TAG_DOMAINS):
        raise RecordingError(f"attribute 'format': expected {FORMAT_TAG!r} or {FORMAT_TAG_DOMAINS!r}, "
                             f"got {_show(tag)}")
    if "domain" not in attrs:
        return "if"
    domain = _scalar(attrs, "domain")
    if domain not in DOMAINS:
        raise RecordingError(f"attribute 'domain': expected one of {', '.join(DOMAINS)}, got {_show(domain)}")
    if domain != "if" and tag == FORMAT_TAG:
        raise RecordingError(f"attribute 'domain': {domain!r} needs format {FORMAT_TAG_DOMAINS!r}, got {tag!r}")
    return domain


def _check_domain_shape(domain: str, shape: tuple[int, ...]) -> None:
    """A CW recording holds one channel: /iq is (n_pulses, 1)."""
    if domain == "cw" and shape[1] != 1:
        raise RecordingError(f"dataset '/iq': a 'cw' recording has shape (n_pulses, 1), got {shape}")


def _metadata(attrs: dict[str, Any]) -> tuple[RadarConfig, RadarSite, datetime]:
    values = {n: _float_attr(attrs, n) for n in _CONFIG_ATTRS}
    values["range_offset_m"] = _float_attr(attrs, "range_offset_m", default=0.0)
    try:
        config = RadarConfig(**values)
    except Invalid as exc:
        raise _config_error(exc) from None
    site_values = {n: _float_attr(attrs, n) for n in _SITE_ATTRS}
    try:
        site = RadarSite(lat_deg=site_values["radar_lat_deg"], lon_deg=site_values["radar_lon_deg"],
                         alt_m=site_values["radar_alt_m"])
    except Invalid as exc:
        raise RecordingError(f"attribute 'radar_{exc.loc.split('.')[0]}': {exc.msg}") from None
    return config, site, _start_time(attrs)


def _check_iq_header(shape: tuple[int, ...] | None, dtype: np.dtype, max_cells: int,
                     max_bytes: int = MAX_IQ_BYTES) -> None:
    """Shape, element type and size from the header alone (nothing allocated yet)."""
    if shape is None:
        raise RecordingError("dataset '/iq': null dataspace (no data)")
    if len(shape) != 2:
        raise RecordingError(f"dataset '/iq': expected 2-D (n_chirps, n_samples), got shape {shape}")
    if shape[0] < 1 or shape[1] < 1:
        raise RecordingError(f"dataset '/iq': empty shape {shape}")
    if dtype.kind != "c" or dtype.itemsize not in (8, 16):
        raise RecordingError(f"dataset '/iq': expected complex64 or complex128, got {dtype}")
    if shape[0] * shape[1] > max_cells:
        raise RecordingError(
            f"dataset '/iq': {shape[0]}x{shape[1]} cells exceed the limit of {max_cells}")
    if shape[0] * shape[1] * dtype.itemsize > max_bytes:
        raise RecordingError(f"dataset '/iq': {shape[0] * shape[1] * dtype.itemsize} bytes exceed "
                             f"the limit of {max_bytes}")


def _check_rid_header(name: str, shape: tuple[int, ...] | None, dtype: np.dtype) -> None:
    """/remote_id: (n, 25) uint8; /remote_id_time_s: (n,) real numbers; n <= MAX_RID_MESSAGES."""
    if shape is None:
        raise RecordingError(f"dataset '/{name}': null dataspace (no data)")
    if name == "remote_id":
        if len(shape) != 2 or shape[1] != RID_MESSAGE_BYTES or shape[0] > MAX_RID_MESSAGES:
            raise RecordingError(f"dataset '/remote_id': expected shape (n, 25), got {shape}")
        if dtype.kind != "u" or dtype.itemsize != 1:
            raise RecordingError(f"dataset '/remote_id': expected uint8, got {dtype}")
    else:
        if len(shape) != 1 or shape[0] > MAX_RID_MESSAGES:
            raise RecordingError(f"dataset '/remote_id_time_s': expected shape (n,), got {shape}")
        if dtype.kind not in "fiu" or dtype.itemsize > 16:
            raise RecordingError(f"dataset '/remote_id_time_s': expected real numbers, got {dtype}")


def _native(a: np.ndarray) -> np.ndarray:
    """The array in native byte order (big-endian files are valid data)."""
    return a if a.dtype.isnative else a.astype(a.dtype.newbyteorder("="))


def _check_iq_values(iq: np.ndarray) -> None:
    bad = int(iq.size - np.count_nonzero(np.isfinite(iq)))
    if bad:
        raise RecordingError(f"dataset '/iq': {bad} non-finite values (NaN/Inf)")


def _check_rid(rid: np.ndarray | None, times: np.ndarray | None) -> None:
    if rid is None:
        if times is not None:
            raise RecordingError("dataset '/remote_id_time_s' present without '/remote_id'")
        return
    if rid.ndim != 2 or rid.shape[1] != RID_MESSAGE_BYTES:
        raise RecordingError(f"dataset '/remote_id': expected shape (n, 25), got {rid.shape}")
    if rid.dtype != np.uint8:
        raise RecordingError(f"dataset '/remote_id': expected uint8, got {rid.dtype}")
    if times is not None:
        if times.shape != (rid.shape[0],):
            raise RecordingError(
                f"dataset '/remote_id_time_s': expected shape ({rid.shape[0]},), got {times.shape}")
        if not np.all(np.isfinite(times)):
            raise RecordingError("dataset '/remote_id_time_s': non-finite values")
        far = np.abs(times.astype(np.float64)) > MAX_RID_TIME_S
        if np.any(far):
            raise RecordingError(f"dataset '/remote_id_time_s': {int(np.count_nonzero(far))} values more than "
                                 f"{MAX_RID_TIME_S:,.0f} s from start_time (got {float(times[far][0]):g})")


def _simulation_attr(attrs: dict[str, Any]) -> str | None:
    """The JSON ground truth of a simulated file. Parsed once here (~15 us) so that a
    corrupt one is bad input, not a JSONDecodeError in `authn inspect`."""
    if "simulation" not in attrs:
        return None
    value = _scalar(attrs, "simulation")
    if not isinstance(value, str):
        raise RecordingError("attribute 'simulation': expected a JSON string")
    try:
        json.loads(value)
    except (ValueError, RecursionError):
        raise RecordingError("attribute 'simulation': not valid JSON") from None
    return value


def _rid_source_attr(attrs: dict[str, Any]) -> str | None:
    """`remote_id_source`: absent, or "capture" (the message times are a sniffer's)."""
    if "remote_id_source" not in attrs:
        return None
    value = _scalar(attrs, "remote_id_source")
    if value != "capture":
        raise RecordingError(f"attribute 'remote_id_source': expected 'capture', got {_show(value)}")
    return value


def _check_rid_source(source: str | None, times: np.ndarray | None) -> None:
    if source is not None and (source != "capture" or times is None):
        raise RecordingError("remote_id_source: 'capture' needs /remote_id and /remote_id_time_s"
                             if source == "capture" else f"remote_id_source: expected 'capture', got {_show(source)}")


#: Every attribute the format defines; others are ignored (never even read).
_ATTR_NAMES = ("format", "domain", *_CONFIG_ATTRS, "range_offset_m", *_SITE_ATTRS, "start_time", "simulation",
               "remote_id_source")

#: What h5py, numpy and the OS raise on corrupt, truncated or hostile files (bit flips in HDF5
#: metadata give RuntimeError/ValueError/KeyError/TypeError/OSError; encrypted or unknown-method
#: zip members RuntimeError/NotImplementedError). (MemoryError and programming errors such as
#: AttributeError are left alone: they are system faults, not bad input.)
_READ_ERRORS = (OSError, ValueError, KeyError, IndexError, TypeError, RuntimeError, OverflowError,
                NotImplementedError, EOFError, struct.error, zlib.error)


def _read_errors() -> tuple[type[Exception], ...]:
    """`_READ_ERRORS` and what zipfile and lzma raise (an .npz read): imported here, in an
    `except` clause that only an exception evaluates, so an HDF5 read never imports them (~4 ms
    of a cold check)."""
    import lzma
    import zipfile

    return _READ_ERRORS + (zipfile.BadZipFile, lzma.LZMAError)


def _reason(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    text = text if len(text) <= 80 else text[:77] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


# --- HDF5 ------------------------------------------------------------------------


def _h5_attrs(f: Any) -> dict[str, Any]:
    """The format's attributes only, into one dict, each read once: an extra attribute of an
    opaque or corrupt type is never touched, a defined one that cannot be read is named."""
    from h5py import h5a

    out: dict[str, Any] = {}
    attrs, fid = f.attrs, f.id
    for name in _ATTR_NAMES:
        try:
            aid = h5a.open(fid, name.encode())  # no `name in attrs` first: ~3 us per attribute saved
            out[name] = _h5_attr_value(aid, attrs, name)
        except KeyError:
            continue  # absent: _metadata names it if it is required
        except _READ_ERRORS as exc:
            raise RecordingError(f"attribute '{name}': unreadable ({_reason(exc)})") from None
    return out


def _h5_attr_value(aid: Any, attrs: Any, name: str) -> Any:
    """The value `attrs[name]` gives, read from the attribute's open `aid`: the format's own types
    (scalar float64, scalar variable-length string) here, minus h5py's dispatch and a second open
    by name; any other type through h5py."""
    from h5py import h5s, h5t

    if aid.get_space().get_simple_extent_type() == h5s.SCALAR:
        htype = aid.get_type()
        if htype.equal(h5t.IEEE_F64LE):
            value = np.empty((), dtype="<f8")
            aid.read(value, mtype=h5t.IEEE_F64LE)
            return value[()]
        if isinstance(htype, h5t.TypeStringID) and htype.is_variable_str():
            dtype = aid.dtype
            text = np.zeros((), dtype=dtype)
            aid.read(text, mtype=h5t.py_create(dtype))
            return text[()].decode("utf-8", "surrogateescape")  # as h5py decodes a variable-length string
    return attrs[name]


def _h5_dataset(f: Any, name: str, required: bool = False) -> Any:
    """The dataset `/name` if it is stored in this file: a hard link to a dataset with
    contiguous or chunked storage. Soft and external links, external raw storage and
    virtual datasets point elsewhere (another file, a FIFO): refused, so nothing can
    block and the file's hash covers all the data."""
    import h5py

    try:
        link = f.get(name, getlink=True)
        if link is None:
            if required:
                raise RecordingError(f"missing dataset '/{name}'")
            return None
        if not isinstance(link, h5py.HardLink):
            kind = ("a soft link" if isinstance(link, h5py.SoftLink) else
                    "an external link" if isinstance(link, h5py.ExternalLink) else "not a hard link")
            raise RecordingError(f"dataset '/{name}': is {kind}; only data stored in the file are read")
        ds = f.get(name)
        if not isinstance(ds, h5py.Dataset):
            got = "an object that cannot be opened" if ds is None else type(ds).__name__
            raise RecordingError(f"dataset '/{name}': expected a dataset, got {got}")
        if ds.is_virtual:
            raise RecordingError(f"dataset '/{name}': virtual datasets are refused")
        if ds.external is not None:
            raise RecordingError(f"dataset '/{name}': external raw storage is refused")
    except RecordingError:
        raise
    except _READ_ERRORS as exc:
        raise RecordingError(f"dataset '/{name}': unreadable ({_reason(exc)})") from None
    return ds


_GCOL = b"GCOL\x01\x00\x00\x00"  # global heap collection signature, version 1, reserved
#: Most global heap collections, and the largest one, that a recording may hold: ours has
#: one of 4 KiB (three short strings). Bounds the Python walk below on a hostile file.
MAX_GLOBAL_HEAPS = 64
MAX_GLOBAL_HEAP_BYTES = 2**20


def _check_global_heaps(path: Path, iq: Any) -> None:
    """Refuse a global heap collection that HDF5 would parse forever.

    Variable-length string attributes (format, start_time, simulation) live in global
    heap collections. HDF5 (2.0.0 included) walks a collection's objects advancing by
    each object's size; a free-space object of size 0 (a bit flip in the collection size
    makes the walk run into zeroed space) never advances: an infinite loop in C that no
    signal interrupts. Found by tests/fuzz/test_reader_properties.py.

    We walk every collection found outside the /iq raw data (the metadata: a few KB,
    ~15 us) the same way first; more than MAX_GLOBAL_HEAPS collections or one larger than
    MAX_GLOBAL_HEAP_BYTES is refused too (bounds this walk). A contiguous /iq's own bytes are skipped for speed, so a
    collection deliberately planted inside them is not seen (residual risk; chunked /iq:
    the whole file is scanned).
    """
    try:
        start, length = iq.id.get_offset(), iq.id.get_storage_size()
    except _READ_ERRORS:
        start = length = None
    fd = os.open(path, os.O_RDONLY | _O_NONBLOCK)
    try:
        size = os.fstat(fd).st_size
        regions = [(0, size)] if start is None or not 0 <= start <= size else [(0, start), (start + length, size)]
        head = os.pread(fd, 16, 0)
        # size of lengths: superblock v0/1 byte 14, v2/3 byte 10 (8 in anything h5py writes)
        at = {0: 14, 1: 14, 2: 10, 3: 10}.get(head[8] if len(head) > 8 else -1)
        lsize = head[at] if at is not None and at < len(head) and head[at] in (2, 4, 8) else 8
        found = 0
        for lo, hi in regions:
            chunk = os.pread(fd, hi - lo, lo) if hi > lo else b""
            pos = chunk.find(b"GCOL")  # the 4-byte needle: a trailing NUL makes find() 10x slower
            while pos >= 0:
                if chunk[pos:pos + 8] == _GCOL:
                    found += 1
                    if found > MAX_GLOBAL_HEAPS:
                        raise RecordingError(f"{path}: more than {MAX_GLOBAL_HEAPS} HDF5 global heap "
                                             f"collections")
                    _walk_collection(path, fd, lo + pos, lsize, size)
                pos = chunk.find(b"GCOL", pos + 4)
    finally:
        os.close(fd)


def _walk_collection(path: Path, fd: int, addr: int, lsize: int, file_size: int) -> None:
    coll = int.from_bytes(os.pread(fd, lsize, addr + 8), "little")
    if addr + coll > file_size:  # HDF5 fails to read past the end of the file itself
        return
    if coll > MAX_GLOBAL_HEAP_BYTES:
        raise RecordingError(f"{path}: HDF5 global heap of {coll} bytes at byte {addr} exceeds the "
                             f"limit of {MAX_GLOBAL_HEAP_BYTES}")
    data = os.pread(fd, coll, addr)
    hdr = 8 + lsize  # object header: index(2) refcount(2) reserved(4) size(lsize)
    p = 8 + lsize
    while p + hdr <= coll:
        idx = int.from_bytes(data[p:p + 2], "little")
        obj = int.from_bytes(data[p + 8:p + 8 + lsize], "little")
        need = obj if idx == 0 else hdr + (obj + 7) // 8 * 8
        if need <= 0:
            raise RecordingError(f"{path}: corrupt HDF5 global heap at byte {addr} "
                                 f"(an empty free-space object; HDF5 would loop forever)")
        p += need


@dataclass(frozen=True)
class _Parts:
    """A return's metadata and Remote ID, every header checked, and its IQ: the open HDF5 dataset
    (read by the caller while the file is open), the array of an .npz, or None when only the
    header was read (`_h5_parts`, `_npz_parts`)."""

    iq: Any
    shape: tuple[int, ...]
    attrs: dict[str, Any]
    domain: str
    config: RadarConfig
    site: RadarSite
    start_time: datetime
    source: str | None
    remote_id: np.ndarray | None
    remote_id_time_s: np.ndarray | None


def _open_h5(path: Path):
    import h5py

    try:
        return h5py.File(path, "r")
    except _READ_ERRORS:
        raise RecordingError(f"{path}: not a readable HDF5 file (truncated or corrupt)") from None


def _h5_parts(f: Any, path: Path, max_cells: int, max_bytes: int) -> _Parts:
    """The datasets and metadata of an open file, every header checked before any data is read:
    what `read_recording` and `read_header` share."""
    ds = _h5_dataset(f, "iq", required=True)
    r = _h5_dataset(f, "remote_id")
    t = _h5_dataset(f, "remote_id_time_s")
    _check_global_heaps(path, ds)
    attrs = _h5_attrs(f)
    domain = _domain(attrs)
    config, site, when = _metadata(attrs)
    source = _rid_source_attr(attrs)
    try:
        _check_iq_header(ds.shape, ds.dtype, max_cells, max_bytes)
        _check_domain_shape(domain, ds.shape)
        for name, d in (("remote_id", r), ("remote_id_time_s", t)):
            if d is not None:
                _check_rid_header(name, d.shape, d.dtype)
    except (TypeError, ValueError, KeyError) as exc:  # a type h5py cannot map to numpy
        if isinstance(exc, RecordingError):
            raise
        raise RecordingError(f"{path}: unsupported datatype ({_reason(exc)})") from None
    rid, times = _h5_remote_id(r, t, path)
    _check_rid(rid, times)
    _check_rid_source(source, times)
    return _Parts(ds, (int(ds.shape[0]), int(ds.shape[1])), attrs, domain, config, site, when, source, rid, times)


def _h5_remote_id(r: Any, t: Any, path: Path) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The Remote ID datasets' values; an unreadable one is named."""
    rid = times = None
    name = "remote_id"
    try:
        if r is not None:
            rid = np.asarray(r[()], dtype=np.uint8)
        name = "remote_id_time_s"
        if t is not None:
            times = np.asarray(t[()]).astype(np.float64)
    except _READ_ERRORS as exc:
        raise _unreadable(path, exc, name) from None
    return rid, times


def _unreadable(path: Path, exc: BaseException, name: str) -> RecordingError:
    return RecordingError(f"{path}: dataset '/{name}' cannot be read (truncated or corrupt; {_reason(exc)})")


def _read_h5(path: Path, max_cells: int, max_bytes: int) -> Recording:
    with _open_h5(path) as f:
        parts = _h5_parts(f, path, max_cells, max_bytes)
        ds = parts.iq
        try:
            iq = np.empty(ds.shape, ds.dtype.newbyteorder("="))
            ds.read_direct(iq)  # ~0.1 ms against ~0.3 ms for ds[()] on a paper cube; HDF5 byte-swaps
        except _READ_ERRORS as exc:
            raise _unreadable(path, exc, "iq") from None
    _check_iq_values(iq)
    return Recording(parts.config, parts.site, parts.start_time, iq, parts.remote_id, parts.remote_id_time_s,
                     _simulation_attr(parts.attrs), parts.domain, parts.source)


def _attrs_of(rec: Recording) -> dict[str, Any]:
    attrs: dict[str, Any] = {"format": FORMAT_TAG if rec.domain == "if" else FORMAT_TAG_DOMAINS,
                             "domain": rec.domain}
    attrs.update(rec.config.to_dict())
    attrs["radar_lat_deg"] = rec.site.lat_deg
    attrs["radar_lon_deg"] = rec.site.lon_deg
    attrs["radar_alt_m"] = rec.site.alt_m
    attrs["start_time"] = rec.start_time.astimezone(timezone.utc).isoformat()
    if rec.simulation is not None:
        attrs["simulation"] = rec.simulation
    if rec.remote_id_source is not None:
        attrs["remote_id_source"] = rec.remote_id_source
    return attrs


def _write_h5(rec: Recording, path: Path) -> None:
    import h5py

    with h5py.File(path, "w") as f:
        for k, v in _attrs_of(rec).items():
            f.attrs[k] = v
        f.create_dataset("iq", data=rec.iq)
        if rec.remote_id is not None:
            f.create_dataset("remote_id", data=rec.remote_id)
        if rec.remote_id_time_s is not None:
            f.create_dataset("remote_id_time_s", data=rec.remote_id_time_s)


# --- NPZ -------------------------------------------------------------------------

_NPY_VERSIONS = ((1, 0), (2, 0), (3, 0))


def _npy_header(fh: Any, check: Any) -> tuple[tuple[int, ...], bool, np.dtype]:
    """(shape, Fortran order, dtype) of an open .npy member from its header, `check(shape, dtype)`
    run on them before anything else is read."""
    version = np.lib.format.read_magic(fh)
    if version not in _NPY_VERSIONS:
        raise ValueError(f"unsupported .npy version {version}")
    reader = (np.lib.format.read_array_header_1_0 if version == (1, 0)
              else np.lib.format.read_array_header_2_0)
    shape, fortran, dtype = reader(fh)
    shape = tuple(shape)
    check(shape, dtype)
    return shape, fortran, dtype


def _npz_member(zf: zipfile.ZipFile, member: str, check: Any) -> np.ndarray:
    """One .npy member: its header is read and `check(shape, dtype)` run before any data
    are allocated; object (pickled) arrays are refused."""
    with zf.open(member) as fh:
        shape, fortran, dtype = _npy_header(fh, check)
        if dtype.hasobject:
            raise RecordingError(f"member '{member}': object arrays (pickles) are not read")
        buf = bytearray(math.prod(shape) * dtype.itemsize)  # bounded by check
        if fh.readinto(buf) != len(buf):
            raise EOFError("member shorter than its header says")
    return np.frombuffer(buf, dtype).reshape(shape, order="F" if fortran else "C")


def _attr_member_check(name: str) -> Any:
    def check(shape: tuple[int, ...], dtype: np.dtype) -> None:
        if math.prod(shape) * dtype.itemsize > MAX_NPZ_ATTR_BYTES:
            raise RecordingError(f"attribute '{name}': {shape} {dtype} exceeds {MAX_NPZ_ATTR_BYTES} bytes")
    return check


def _npz_parts(path: Path, max_cells: int, max_bytes: int, with_iq: bool) -> _Parts:
    """What `read_recording` (`with_iq`) and `read_header` (the IQ's header only) share of an .npz:
    each member's header checked before its data are read; object arrays refused."""
    import zipfile

    name = "iq"
    try:
        with zipfile.ZipFile(path) as zf:
            members = {n.removesuffix(".npy"): n for n in zf.namelist()}
            if "iq" not in members:
                raise RecordingError("missing dataset '/iq'")
            check_iq = lambda s, d: _check_iq_header(s, d, max_cells, max_bytes)  # noqa: E731
            iq = _npz_member(zf, members["iq"], check_iq) if with_iq else None
            shape = tuple(iq.shape) if iq is not None else _npz_header_only(zf, members["iq"], check_iq)
            attrs = {}
            for name in _ATTR_NAMES:
                if name in members:
                    attrs[name] = _npz_member(zf, members[name], _attr_member_check(name))
            domain = _domain(attrs)
            _check_domain_shape(domain, shape)
            config, site, when = _metadata(attrs)
            source = _rid_source_attr(attrs)
            data: dict[str, np.ndarray | None] = {"remote_id": None, "remote_id_time_s": None}
            for name in data:
                if name in members:
                    data[name] = _npz_member(zf, members[name], lambda s, d, n=name: _check_rid_header(n, s, d))
    except RecordingError:
        raise
    except _read_errors() as exc:
        raise RecordingError(f"{path}: not a readable .npz file (truncated or corrupt; "
                             f"member '{name}': {_reason(exc)})") from None
    rid = None if data["remote_id"] is None else np.asarray(data["remote_id"], dtype=np.uint8)
    times = None if data["remote_id_time_s"] is None else data["remote_id_time_s"].astype(np.float64)
    _check_rid(rid, times)
    _check_rid_source(source, times)
    return _Parts(iq, shape, attrs, domain, config, site, when, source, rid, times)


def _read_npz(path: Path, max_cells: int, max_bytes: int) -> Recording:
    parts = _npz_parts(path, max_cells, max_bytes, with_iq=True)
    iq = _native(parts.iq)
    _check_iq_values(iq)
    return Recording(parts.config, parts.site, parts.start_time, iq, parts.remote_id, parts.remote_id_time_s,
                     _simulation_attr(parts.attrs), parts.domain, parts.source)


def _write_npz(rec: Recording, path: Path) -> None:
    arrays: dict[str, np.ndarray] = {k: np.asarray(v) for k, v in _attrs_of(rec).items()}
    arrays["iq"] = rec.iq
    if rec.remote_id is not None:
        arrays["remote_id"] = rec.remote_id
    if rec.remote_id_time_s is not None:
        arrays["remote_id_time_s"] = rec.remote_id_time_s
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(buf.getvalue())


# --- public API ------------------------------------------------------------------

_HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"
_O_NONBLOCK = getattr(os, "O_NONBLOCK", 0)


def _sniff(path: Path, max_file_bytes: int) -> bytes:
    """First 8 bytes of a regular file no larger than max_file_bytes.

    stat before open: a FIFO, device or directory is refused (opening a FIFO blocks until
    a writer appears); the sniffing open is non-blocking and re-checked with fstat. h5py
    and zipfile then open the path again: swapping the file for a FIFO in that window
    needs write access to its directory, which is out of scope.
    """
    try:
        st = os.stat(path)
        if stat.S_ISREG(st.st_mode):
            fd = os.open(path, os.O_RDONLY | _O_NONBLOCK)
            try:
                st = os.fstat(fd)
                head = os.read(fd, 8) if stat.S_ISREG(st.st_mode) else b""
            finally:
                os.close(fd)
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        raise RecordingError(f"{path}: cannot open ({getattr(exc, 'strerror', None) or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise RecordingError(f"{path}: is a directory, not a recorded-return file")
    if not stat.S_ISREG(st.st_mode):
        raise RecordingError(f"{path}: not a regular file (FIFO, socket or device); only regular "
                             f"files are read")
    if st.st_size > max_file_bytes:
        raise RecordingError(f"{path}: {st.st_size} bytes exceed the limit of {max_file_bytes}")
    return head


#: What a recorded-return file may be called: the suffix names the container (docs/format.md).
RECORDING_SUFFIXES = (".h5", ".hdf5", ".npz")


def recordings_in(directory: Path, recursive: bool = False) -> list[Path]:
    """The recorded-return files of `directory` (`RECORDING_SUFFIXES`; `recursive`: of its subfolders
    too), sorted by path: the time order `authn import` gives its numbered dwells."""
    found = directory.rglob("*") if recursive else directory.iterdir()
    return sorted(f for f in found if f.suffix.lower() in RECORDING_SUFFIXES and f.is_file())


def read_recording(path: str | Path, max_cells: int = MAX_IQ_CELLS, *,
                   max_bytes: int = MAX_IQ_BYTES, max_file_bytes: int = MAX_FILE_BYTES) -> Recording:
    """Read and validate a recorded return (.h5/.hdf5 or .npz; sniffed by content).

    Bad input of any kind raises RecordingError with one line naming the field.
    """
    return _by_container(Path(path), max_cells, max_bytes, max_file_bytes, _read_npz, _read_h5)


def _by_container(path: Path, max_cells: int, max_bytes: int, max_file_bytes: int, npz: Any, h5: Any) -> Any:
    """Sniff the container and run its reader; every failure is one line of RecordingError."""
    try:
        head = _sniff(path, max_file_bytes)
        if head.startswith(b"PK"):
            return npz(path, max_cells, max_bytes)
        if head == _HDF5_MAGIC or path.suffix.lower() in (".h5", ".hdf5"):
            return h5(path, max_cells, max_bytes)
    except RecordingError as exc:
        text = str(exc)
        if "\n" in text or "\r" in text:  # a path or value with a line break: keep one line
            raise RecordingError(" ".join(text.split())) from None
        raise
    except _read_errors() as exc:  # last resort: nothing on the read path escapes unconverted
        raise RecordingError(f"{path}: unreadable ({_reason(exc)})") from None
    raise RecordingError(f"{path}: neither HDF5 nor .npz")


@dataclass(frozen=True, eq=False)
class Header:
    """What a recorded return says about itself without its IQ: waveform, site, time, shape
    and the Remote ID messages (small). `authn check --track` validates a whole track with
    these (one waveform, one claim, time order) before it reads any dwell's IQ."""

    config: RadarConfig
    site: RadarSite
    start_time: datetime
    shape: tuple[int, int]
    domain: str = "if"
    remote_id: np.ndarray | None = None
    remote_id_time_s: np.ndarray | None = None

    @property
    def n_chirps(self) -> int:
        return int(self.shape[0])

    @property
    def mid_time(self) -> datetime:
        return self.start_time + timedelta(seconds=self.n_chirps * self.config.pri_s / 2)


def _header_h5(path: Path, max_cells: int, max_bytes: int) -> Header:
    with _open_h5(path) as f:
        return _header_of(_h5_parts(f, path, max_cells, max_bytes))


def _header_of(parts: _Parts) -> Header:
    return Header(parts.config, parts.site, parts.start_time, (int(parts.shape[0]), int(parts.shape[1])),
                  parts.domain, parts.remote_id, parts.remote_id_time_s)


def _npz_header_only(zf: zipfile.ZipFile, member: str, check: Any) -> tuple[int, ...]:
    """The shape of one .npy member from its header (its data are not read)."""
    with zf.open(member) as fh:
        return _npy_header(fh, check)[0]


def _header_npz(path: Path, max_cells: int, max_bytes: int) -> Header:
    return _header_of(_npz_parts(path, max_cells, max_bytes, with_iq=False))


def read_header(path: str | Path, max_cells: int = MAX_IQ_CELLS, *,
                max_bytes: int = MAX_IQ_BYTES, max_file_bytes: int = MAX_FILE_BYTES) -> Header:
    """Read and validate a recorded return's metadata and Remote ID, not its IQ: the same
    refusals as `read_recording` except the IQ values (NaN/Inf), which only a full read sees."""
    return _by_container(Path(path), max_cells, max_bytes, max_file_bytes, _header_npz, _header_h5)


def write_recording(rec: Recording, path: str | Path) -> Path:
    """Write a recorded return; the suffix (.npz or anything else = HDF5) picks the container."""
    path = Path(path)
    _check_iq_header(tuple(rec.iq.shape), rec.iq.dtype, max(MAX_IQ_CELLS, rec.iq.size),
                     max(MAX_IQ_BYTES, rec.iq.nbytes))
    if rec.domain not in DOMAINS:
        raise RecordingError(f"domain: expected one of {', '.join(DOMAINS)}, got {_show(rec.domain)}")
    _check_domain_shape(rec.domain, tuple(rec.iq.shape))
    _check_iq_values(rec.iq)
    _check_rid(rec.remote_id, rec.remote_id_time_s)
    _check_rid_source(rec.remote_id_source, rec.remote_id_time_s)
    path.parent.mkdir(parents=True, exist_ok=True)
    (_write_npz if path.suffix.lower() == ".npz" else _write_h5)(rec, path)
    return path
