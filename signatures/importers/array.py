"""A numpy (.npy/.npz) or MATLAB (.mat v4/v5 via scipy, v7.3 via h5py) array as recorded
returns of any domain: dechirped IF, range-compressed slow time, or CW Doppler IQ.

Nothing is unpickled (`allow_pickle=False`; MATLAB cells, structs and objects are refused).
The array's rows are pulses (slow time) and its columns fast-time samples or range bins
unless the caller says otherwise; real I and Q may come as two variables or interleaved.
The waveform each domain is recorded under is in docs/import.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from signatures.sim.domain import cw_config, range_config
from signatures.errors import SignaturesError
from signatures.importers.dwell import Dwell, analytic_half_rate, radar_config

__all__ = ["ArraySource", "Waveform", "dwells", "load"]

_MAT73 = b"MATLAB 7.3 MAT-file"
_HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"


@dataclass(frozen=True)
class ArraySource:
    """Which array(s) of the file and how they are laid out."""

    var: str | None = None  # the variable (.npz/.mat); None: the file's only one
    imag_var: str | None = None  # real Q in a second variable (then `var` holds I)
    interleaved: bool = False  # real I, Q, I, Q, ... along the stored array's last axis
    transpose: bool = False  # stored as (fast time or range bins) x pulses


@dataclass(frozen=True)
class Waveform:
    """The radar's numbers as the user gives them (which are needed depends on the domain)."""

    carrier_hz: float
    pri_s: float | None = None
    bandwidth_hz: float | None = None
    ramp_s: float | None = None
    sample_rate_hz: float | None = None
    range_bin_m: float | None = None
    first_range_m: float | None = None


# --- reading ---------------------------------------------------------------------------

def _numeric(a: object, what: str) -> np.ndarray:
    arr = np.asarray(a) if isinstance(a, np.ndarray) else None
    if arr is None or arr.dtype.kind not in "iufc":
        kind = type(a).__name__ if arr is None else str(arr.dtype)
        raise SignaturesError(f"{what}: not a numeric array ({kind}; cells, structs and objects are not read)")
    return arr


def _pick(names: list[str], var: str | None, path: Path) -> str:
    if var is not None:
        if var not in names:
            raise SignaturesError(f"--var: {path} has no variable {var!r} (it has: {', '.join(names) or 'none'})")
        return var
    if len(names) != 1:
        raise SignaturesError(f"{path} holds {len(names)} variables ({', '.join(names)}); name one with --var")
    return names[0]


def _load_npy(path: Path, var: str | None) -> dict[str, np.ndarray]:
    try:
        data = np.load(path, allow_pickle=False)
        if isinstance(data, np.ndarray):
            if var is not None:
                raise SignaturesError(f"--var: {path} is a single .npy array, it has no variables")
            return {"": data}
        with data:
            return {n: data[n] for n in data.files}
    except SignaturesError:
        raise
    except (OSError, ValueError, EOFError) as exc:  # pickled objects, truncation, not numpy
        raise SignaturesError(f"{path}: not a readable numpy file ({' '.join(str(exc).split())[:100]})") from None


def _load_mat5(path: Path) -> dict[str, np.ndarray]:
    import scipy.io

    try:
        data = scipy.io.loadmat(path, squeeze_me=False, mat_dtype=False, struct_as_record=True)
    except (OSError, ValueError, TypeError, NotImplementedError, EOFError) as exc:
        raise SignaturesError(f"{path}: not a readable MATLAB file ({' '.join(str(exc).split())[:100]})") from None
    return {k: v for k, v in data.items() if not k.startswith("__")}


def _load_mat73(path: Path, var: str | None) -> dict[str, np.ndarray]:
    """MATLAB v7.3 (HDF5): column-major, so h5py's shape is MATLAB's reversed (transposed
    back here); complex data are a compound of `real` and `imag`."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            names = [n for n in f if not n.startswith("#")]
            name = _pick(names, var, path)
            ds = f.get(name)
            if not isinstance(ds, h5py.Dataset):
                raise SignaturesError(f"{path}: variable {name!r} is a struct or cell, not a numeric array")
            raw = ds[()]
            cls = ds.attrs.get("MATLAB_class", b"")
    except SignaturesError:
        raise
    except (OSError, ValueError, KeyError, TypeError, RuntimeError) as exc:
        raise SignaturesError(f"{path}: not a readable MATLAB v7.3 file ({' '.join(str(exc).split())[:100]})") from None
    if isinstance(cls, bytes) and cls not in (b"double", b"single", b"int8", b"int16", b"int32", b"int64", b"uint8",
                                              b"uint16", b"uint32", b"uint64", b""):
        raise SignaturesError(f"{path}: variable {name!r} is a MATLAB {cls.decode(errors='replace')}, not numeric")
    if raw.dtype.names and set(raw.dtype.names) == {"real", "imag"}:
        raw = raw["real"] + 1j * raw["imag"]
    return {name: np.asarray(raw).T}


def load(path: Path, src: ArraySource) -> np.ndarray:
    """The complex (or real, for real IF) samples of the file, as stored (no orientation yet)."""
    try:
        with path.open("rb") as fh:
            head = fh.read(520)
    except OSError as exc:
        raise SignaturesError(f"{path}: cannot open ({exc.strerror or exc})") from None
    suffix = path.suffix.lower()
    if suffix in (".npy", ".npz"):
        arrays = _load_npy(path, src.var)
    elif suffix == ".mat":
        if head.startswith(_MAT73) or head[512:520] == _HDF5_MAGIC:
            arrays = _load_mat73(path, src.var)
        else:
            arrays = _load_mat5(path)
    else:
        raise SignaturesError(f"{path}: expected a .npy, .npz or .mat file")
    names = [n for n in arrays if n]
    name = _pick(names, src.var, path) if names else ""
    first = _numeric(arrays[name], f"variable {name!r}" if name else str(path))
    if src.imag_var is not None:
        if src.interleaved:
            raise SignaturesError("--imag-var and --interleaved exclude each other")
        second = _numeric(arrays[_pick(names, src.imag_var, path)], f"variable {src.imag_var!r}")
        if first.dtype.kind == "c" or second.dtype.kind == "c" or first.shape != second.shape:
            raise SignaturesError(f"--imag-var: I and Q must be real arrays of one shape, got {first.dtype} "
                                  f"{first.shape} and {second.dtype} {second.shape}")
        return first.astype(np.float64) + 1j * second.astype(np.float64)
    if src.interleaved:
        if first.dtype.kind == "c" or first.ndim < 1 or first.shape[-1] % 2:
            raise SignaturesError(f"--interleaved: need a real array with an even last axis, got {first.dtype} "
                                  f"{first.shape}")
        return first[..., 0::2].astype(np.float64) + 1j * first[..., 1::2].astype(np.float64)
    return first


# --- shaping and the waveform ----------------------------------------------------------

def _pulses_first(a: np.ndarray, domain: str, transpose: bool) -> np.ndarray:
    if domain == "cw":
        if a.ndim == 2 and 1 in a.shape:
            a = a.reshape(-1)
        if a.ndim != 1:
            raise SignaturesError(f"--domain cw: expected a vector of pulses, got shape {a.shape}")
        return a.reshape(-1, 1)
    if a.ndim != 2:
        raise SignaturesError(f"--domain {domain}: expected a 2-D array (pulses x "
                              f"{'samples' if domain == 'if' else 'range bins'}), got shape {a.shape}")
    return a.T if transpose else a


def _complex(a: np.ndarray, domain: str) -> np.ndarray:
    if a.dtype.kind == "c":
        return a.astype(np.complex128 if a.dtype == np.complex128 or a.dtype.itemsize > 16 else np.complex64)
    if domain != "if":
        raise SignaturesError(f"--domain {domain}: the samples are real; give complex data, I and Q "
                              f"(--var I --imag-var Q) or interleaved I/Q (--interleaved): magnitudes carry no "
                              f"Doppler sign")
    return analytic_half_rate(a.astype(np.float64 if a.dtype == np.float64 else np.float32))


_FLAGS = {"pri_s": "--pri-s", "bandwidth_hz": "--bandwidth-hz", "ramp_s": "--ramp-s",
          "sample_rate_hz": "--sample-rate-hz", "range_bin_m": "--range-bin-m", "first_range_m": "--first-range-m"}


def _need(w: Waveform, domain: str, names: tuple[str, ...]) -> None:
    flags = _FLAGS
    missing = [flags[n] for n in names if getattr(w, n) is None]
    if missing:
        raise SignaturesError(f"--domain {domain} needs {', '.join(missing)}")
    allowed = set(names) | {"first_range_m"} if domain != "cw" else set(names)
    extra = [flags[n] for n in flags if n not in allowed and getattr(w, n) is not None]
    if extra:
        raise SignaturesError(f"--domain {domain} does not take {', '.join(extra)}")


def check_options(w: Waveform, domain: str) -> None:
    """The numbers the domain needs are given, and none it does not take (before any data
    are read)."""
    for name, flag in {"carrier_hz": "--carrier-hz", **_FLAGS}.items():
        value = getattr(w, name)
        if value is not None and not (math.isfinite(value) and (value > 0 or name == "first_range_m" and value >= 0)):
            raise SignaturesError(f"{flag}: must be a positive number, got {value:g}")
    if domain == "if":
        _need(w, domain, ("pri_s", "bandwidth_hz", "ramp_s", "sample_rate_hz"))
    elif domain == "range":
        _need(w, domain, ("pri_s", "range_bin_m"))
    else:
        if (w.pri_s is None) == (w.sample_rate_hz is None):
            raise SignaturesError("--domain cw needs one of --pri-s or --sample-rate-hz (the IQ sample rate)")
        _need(w, domain, ("pri_s",) if w.pri_s is not None else ("sample_rate_hz",))


def waveform_config(w: Waveform, domain: str, n_cols: int, real_if: bool):
    """The RadarConfig of the domain (docs/import.md; options checked by `check_options`):
    IF as given (the complex rate halves for real samples), range via `range_config`, CW via
    `cw_config` (PRI = 1 / sample rate)."""
    if domain == "if":
        return radar_config("--domain if", carrier_hz=w.carrier_hz, bandwidth_hz=w.bandwidth_hz, ramp_s=w.ramp_s,
                            pri_s=w.pri_s, sample_rate_hz=w.sample_rate_hz / (2 if real_if else 1),
                            range_offset_m=w.first_range_m or 0.0)
    if domain == "range":
        return _checked(lambda: range_config(w.carrier_hz, w.pri_s, w.range_bin_m, w.first_range_m or 0.0, n_cols))
    pri = w.pri_s if w.pri_s is not None else 1.0 / w.sample_rate_hz
    return _checked(lambda: cw_config(w.carrier_hz, pri))


def _checked(build):
    from core.checked import Invalid

    try:
        return build()
    except Invalid as exc:
        raise SignaturesError(f"waveform: radar attribute '{exc.loc.split('.')[0] or 'pri_s'}': {exc.msg}") from None


def dwells(path: Path, src: ArraySource, domain: str, w: Waveform,
           pulses_per_dwell: int | None = None) -> list[Dwell]:
    """The file's samples as dwells of `pulses_per_dwell` pulses (all of them by default;
    a shorter tail is dropped)."""
    check_options(w, domain)
    raw = load(path, src)
    stored = _pulses_first(raw, domain, src.transpose)
    if not np.all(np.isfinite(stored)):
        raise SignaturesError(f"{path}: the samples hold NaN or Inf")
    iq = _complex(stored, domain)
    if iq.shape[0] < 1 or iq.shape[1] < 1:
        raise SignaturesError(f"{path}: no samples (shape {iq.shape})")
    config = waveform_config(w, domain, iq.shape[1], stored.dtype.kind != "c")
    per = iq.shape[0] if pulses_per_dwell is None else pulses_per_dwell
    if per < 1 or per > iq.shape[0]:
        raise SignaturesError(f"--pulses-per-dwell: {per} is outside 1..{iq.shape[0]} (the pulses in the file)")
    return [Dwell(np.ascontiguousarray(iq[i * per:(i + 1) * per]), config, domain, i * per * config.pri_s,
                  f"dwell_{i:06d}") for i in range(iq.shape[0] // per)]
