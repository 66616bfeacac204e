"""Features of returns, array-first: every stage runs on (B, ...) arrays, and one return is a
batch of one (`extract`). The one implementation of the feature maths (docs/features.md).

Why arrays: one return costs ~1,500 Python-level numpy calls, so the interpreter, not the
arithmetic, sets its cost; a batch pays those calls once for all its rows.

Layout: the cube stage (scaling, clutter suppression, range FFT, range profile) runs in
blocks of rows through reused workspaces (`_CUBE_BLOCK_BYTES`: the passes over the cube
are the cost floor, and fresh large arrays cost page faults), CFAR and gating once per
`_SPECTRA_BYTES` of spectra; everything after it works on the (B, chirps, gate bins)
slow-time gates of the whole batch. Only the range FFT and the range profile touch the whole
cube. The CNN patch is built lazily from the row's range spectrum computed again when asked
for (`_PatchColumns`; a torch device keeps the patch columns instead). `extract_many` stacks no
batch-sized input: each block of rows is stacked into a reused workspace (`_Stack`).

Numerics: each cube is scaled by an exact power of two, so every feature but
`peak_amplitude_db` is independent of the IQ scale and no power is squared out of float32
range; divisions use `max(x, tiny)`; logs are floored. Arrays are float32/complex64; scalar
bookkeeping (absolute ranges, the peak amplitude's exponent) is float64.

`cw` cubes (one channel, no range axis) run the same stages: no range FFT, the Doppler bins are
the detector's reference cells (`_cw_detection`), range features are 0.

FFT backends (`fft_backend`): 'numpy' (complex128 transforms, no scipy import: the default of a
single cold check) or 'scipy' (single-precision pocketfft in place: ~2-4x faster on big
batches; a batch job pays scipy's 0.2-0.4 s import once). `device` moves the cube stage to
torch (`signatures.dsp.torch_cube`, e.g. a GPU).
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from dataclasses import fields as dataclass_fields
from functools import cached_property
from typing import NamedTuple

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from signatures.dsp import envelope
from signatures.dsp import feature_vector as F
from signatures.dsp import fft as _fft
from signatures.dsp import flash_period, flash_series, flash_spectrum
from signatures.dsp import rd
from signatures.dsp import timefreq as tf
from signatures.errors import SignaturesError
from signatures.dsp.cube_scale import SAFE_EXPONENT, RowError, prepared
from signatures.radar import RadarConfig
from signatures.recording import DOMAINS
from signatures.dsp.stats import distinct, median, median_last
from signatures.dsp.threads import blas_on_one_thread, one_blas_thread

__all__ = ["DEFAULT_FFT_BACKEND", "MAX_BATCH", "Chooser", "batch_size", "detections", "extract", "extract_batch",
           "extract_iq", "extract_many"]

MAX_BATCH = 1024
#: rows of the cube stage run together while their complex128 FFT workspace fits in this (4 MiB:
#: fastest of 0.5-32 MiB on the paper cube)
_CUBE_BLOCK_BYTES = 4 << 20
#: default memory budget: this share of the available memory, capped at _BUDGET_CAP
_BUDGET_SHARE = 0.25
_BUDGET_CAP = 1 << 30
#: a block's chirps run in chunks of at most this many bytes of complex128 (bounds the
#: workspaces: one `wide` cube is 8 MiB)
_CHUNK_BYTES = 4 << 20
#: complex64 spectra of this many bytes are detected and gated together (`_cube_stage`)
_SPECTRA_BYTES = 32 << 20
#: a batch job's FFT backend: scipy's single-precision transforms (~2-4x numpy's complex128
#: on these cubes; its 0.2-0.4 s import is paid once per batch job)
DEFAULT_FFT_BACKEND = "scipy"
_TINY = F.TINY
_local = threading.local()


@dataclass(frozen=True)
class _Cube:
    """What the cube stage leaves per row (B rows): all the slow-time stage needs."""

    log2_scale: np.ndarray  # (B,) int
    zero: np.ndarray  # (B,) bool: no slow-time signal (all zero, or one chirp repeated: `prepared`)
    profile: np.ndarray  # (B, bins) float32
    mu: np.ndarray  # (B, bins) complex64: range spectrum of the slow-time mean
    detected: np.ndarray  # (B,) bool
    peak_bin: np.ndarray  # (B,) int
    peak_bin_frac: np.ndarray  # (B,) float64
    snr_db: np.ndarray  # (B,) float64
    gate_lo: np.ndarray  # (B,) int
    slow: np.ndarray  # (B, chirps, gate) complex64
    patch_lo: np.ndarray  # (B,) int
    #: row b's patch columns (chirps, patch bins) complex64: `spectrum[:, patch_lo[b]:][:, :patch bins]`
    patch_row: Callable[[int], np.ndarray]

    @cached_property
    def patch_cols(self) -> np.ndarray:
        """(B, chirps, patch bins) complex64: every row's patch columns."""
        return np.stack([self.patch_row(b) for b in range(self.patch_lo.size)])


def batch_size(n_chirps: int, n_samples: int, memory_bytes: int | None = None) -> int:
    """Rows per batch so that the batch's working arrays fit `memory_bytes` (default: a quarter
    of the available memory, at most 1 GiB); between 1 and MAX_BATCH."""
    budget = _default_budget() if memory_bytes is None else int(memory_bytes)
    return int(min(MAX_BATCH, max(1, budget // _bytes_per_return(n_chirps, n_samples))))


def _bytes_per_return(n_chirps: int, n_samples: int, gate_bins: int = F.GATE_BINS) -> int:
    """Peak bytes one row adds to a batch: its input cube as complex64, the patch columns (kept only
    on a torch device; a margin otherwise), and 16 gate-sized complex128 temporaries (Doppler spectrum, powers,
    STFT frames, the flash estimators' fields: ~10 measured with tracemalloc; the cube stage's
    workspaces are per block, not per row). tests/features/test_batch_features.py checks the
    estimate against the measured peak."""
    gate = n_chirps * min(gate_bins, n_samples)
    patch = n_chirps * min(F.PATCH_SHAPE[1], n_samples)
    return 8 * n_chirps * n_samples + 8 * patch + 16 * 16 * gate


def _default_budget() -> int:
    avail = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    if avail is None:
        try:
            avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            avail = 4 << 30
    return int(min(_BUDGET_CAP, avail * _BUDGET_SHARE))


def extract(recording, expected_range_m: float | Chooser | None = None, *, quick: bool = False,
            clutter_suppression: bool = True, fft_backend: str | None = None) -> F.FeatureResult:
    """Features of one `Recording` (see `extract_iq`)."""
    return extract_iq(recording.iq, recording.config, expected_range_m, quick=quick,
                      clutter_suppression=clutter_suppression, domain=recording.domain, fft_backend=fft_backend)


def extract_iq(iq: np.ndarray, config: RadarConfig, expected_range_m: float | Chooser | None = None, *,
               gate_bins: int = F.GATE_BINS, clutter_suppression: bool = True, quick: bool = False,
               domain: str = "if", fft_backend: str | None = None) -> F.FeatureResult:
    """Features of a bare cube (chirps x samples, any numeric dtype): a batch of one.

    `expected_range_m` (range at the dwell, e.g. from Remote ID) centres the gate there and
    counts only a detection within it; it must lie inside the recorded window. A `Chooser`
    instead picks it from the return's targets (`detections`, here from the range profile the
    features compute anyway: no second range FFT). `quick=True`
    computes only `QUICK_FEATURES` (no flash estimator, cadence or CNN patch: the fast tier of
    the run-time-versus-error benchmark); the others are 0 and the patch is empty.

    `domain` (docs/format.md) says what the cube already is: `range` and `cw` cubes are range
    spectra, so no range FFT runs (clutter suppression still removes the slow-time mean of
    every bin); a `cw` cube's one bin is the gate, takes no `expected_range_m` and gives range
    features of 0 (docs/features.md). `fft_backend` ('numpy', 'scipy'; None: the process
    default, `signatures.dsp.fft.backend()`) runs every transform, the lazy patch's included.
    """
    a = np.asarray(iq)
    if a.ndim != 2 or a.shape[0] < 1 or a.shape[1] < 1:
        raise SignaturesError(f"IQ cube must be 2-D (n_chirps, n_samples), got shape {a.shape}")
    backend = _backend(_fft.resolve(fft_backend))
    return _extract(a[None], [config], [expected_range_m], gate_bins, clutter_suppression, domain, [0],
                    backend, quick=quick, labelled=False)[0]


#: A recording's waveform: its config's fields but the range offset (a tuple of them keys a
#: batch group; a checked copy of the config per row cost ~17 us).
_WAVEFORM_FIELDS = tuple(f.name for f in dataclass_fields(RadarConfig) if f.name != "range_offset_m")


def extract_many(recordings: Sequence, expected_range_m: Sequence[float | Chooser | None] | None = None, *,
                 quick: bool = False, memory_bytes: int | None = None, fft_backend: str = DEFAULT_FFT_BACKEND,
                 device: str | None = None) -> list[F.FeatureResult]:
    """Features of any mix of recordings, in input order: rows that share (waveform, cube shape,
    dtype, domain) run batched in chunks of `batch_size`, whatever their range offsets (only
    absolute ranges depend on it: a simulated recording's window is centred on its target).
    `expected_range_m` as `extract_iq`'s, per row (a `Chooser` sees its row's targets from this
    batch's range profile, on `fft_backend`). A bad row raises `SignaturesError` naming its input
    index. `fft_backend` and `device` as `extract_batch`."""
    n = len(recordings)
    expected = _expected(expected_range_m, n)
    fft_backend = _backend(fft_backend)
    torch_device = _device(device)
    out: list[F.FeatureResult | None] = [None] * n
    groups: dict[tuple, list[int]] = {}
    for i, rec in enumerate(recordings):
        iq = np.asarray(rec.iq)
        if iq.ndim != 2 or iq.shape[0] < 1 or iq.shape[1] < 1:
            raise SignaturesError(f"row {i}: IQ cube must be 2-D (n_chirps, n_samples), got shape {iq.shape}")
        waveform = tuple(getattr(rec.config, name) for name in _WAVEFORM_FIELDS)
        groups.setdefault((waveform, iq.shape, iq.dtype.str, rec.domain), []).append(i)
    for (_, shape, _, domain), rows in groups.items():
        step = batch_size(shape[0], shape[1], memory_bytes)
        for s in range(0, len(rows), step):
            part = rows[s:s + step]
            iq = _Stack([np.asarray(recordings[i].iq) for i in part])
            res = _extract(iq, [recordings[i].config for i in part], [expected[i] for i in part],
                           F.GATE_BINS, True, domain, part, fft_backend, torch_device, quick=quick)
            for i, r in zip(part, res):
                out[i] = r
    return out  # type: ignore[return-value]


class _Stack:
    """Rows of equal shape and dtype that `_cube_stage` stacks a block at a time into a reused
    workspace (`_block`): no batch-sized copy of the input (for a `paper` batch of 256, 98 MB of
    fresh pages). Indexing gives a row (int) or a fresh stack of rows (slice)."""

    ndim = 3

    def __init__(self, rows: list[np.ndarray]) -> None:
        self.rows = rows
        self.shape = (len(rows),) + rows[0].shape
        self.dtype = rows[0].dtype

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, key):
        if isinstance(key, slice):
            return np.stack(self.rows[key])
        return self.rows[key]


def _block(iq: np.ndarray | _Stack, b0: int, b1: int) -> np.ndarray:
    """iq[b0:b1] as an array: a view of an array, a workspace stack of a `_Stack`'s rows."""
    if not isinstance(iq, _Stack):
        return iq[b0:b1]
    return np.stack(iq.rows[b0:b1], out=_scratch("stack", (b1 - b0,) + iq.shape[1:], iq.dtype))


def extract_batch(iq: np.ndarray, config: RadarConfig, expected_range_m: Sequence[float | None] | None = None,
                  *, gate_bins: int = F.GATE_BINS, clutter_suppression: bool = True,
                  domain: str = "if", fft_backend: str = DEFAULT_FFT_BACKEND,
                  device: str | None = None) -> list[F.FeatureResult]:
    """`extract_iq(iq[b], config, expected_range_m[b], ...)` for every row b of `iq` (B, chirps,
    samples; any numeric dtype), in one batch.

    `fft_backend`: 'scipy' (default: single-precision pocketfft, the faster; a batch job pays
    scipy's import once) or 'numpy' (complex128 transforms). `device` runs the cube stage in
    torch (`signatures.dsp.torch_cube`; the optional `cnn` extra): None (numpy), 'cpu', 'cuda' or
    'auto' (cuda when available, else numpy); features then match the numpy path's to float32
    rounding, not bit for bit. Bad input in any row raises `SignaturesError` prefixed "row b: ".
    """
    a = np.asarray(iq)
    if a.ndim != 3 or a.shape[1] < 1 or a.shape[2] < 1:
        raise SignaturesError(f"IQ batch must be 3-D (batch, n_chirps, n_samples), got shape {a.shape}")
    expected = _expected(expected_range_m, a.shape[0])
    return _extract(a, [config] * a.shape[0], expected, gate_bins, clutter_suppression, domain,
                    list(range(a.shape[0])), _backend(fft_backend), _device(device))


def _backend(fft_backend: str) -> str:
    if fft_backend not in _fft.BACKENDS:
        raise SignaturesError(f"unknown FFT backend {fft_backend!r} (known: {', '.join(_fft.BACKENDS)})")
    return fft_backend


def _device(device: str | None):
    """The torch device the cube stage runs on, or None for numpy ('auto' without CUDA)."""
    if device is None:
        return None
    try:
        from signatures.dsp import torch_cube
    except ImportError:
        if device == "auto":
            return None
        raise SignaturesError(f"device {device!r} needs torch (the optional 'cnn' extra)") from None
    return torch_cube.resolve(device)


def _expected(expected_range_m: Sequence[float | Chooser | None] | None, n: int) -> list[float | Chooser | None]:
    if expected_range_m is None:
        return [None] * n
    expected = list(expected_range_m)
    if len(expected) != n:
        raise SignaturesError(f"{len(expected)} expected ranges for {n} returns")
    return expected


def _extract(iq: np.ndarray | _Stack, configs: list[RadarConfig], expected: list[float | Chooser | None],
             gate_bins: int, suppress: bool, domain: str, labels: list[int], fft_backend: str = DEFAULT_FFT_BACKEND,
             device=None, *, quick: bool = False, labelled: bool = True) -> list[F.FeatureResult]:
    """The rows' features; `configs[b]` differ at most in their range offset. BLAS runs on one
    thread for a batch (`signatures.dsp.threads`: a batch job is one process per core; one return's
    products are too small to be split, so it skips the ~15 ms of finding the BLAS libraries).
    A bad row's error names it ("row b: ...") when `labelled`."""
    try:
        with one_blas_thread() if iq.shape[0] > 1 else contextlib.nullcontext():
            return _extract_rows(iq, configs, expected, gate_bins, suppress, domain, labels, fft_backend,
                                 device, quick)
    except RowError as exc:
        raise SignaturesError(f"row {exc.row}: {exc.message}" if labelled else exc.message) from None


def _extract_rows(iq: np.ndarray | _Stack, configs: list[RadarConfig], expected: list[float | Chooser | None],
                  gate_bins: int, suppress: bool, domain: str, labels: list[int], fft_backend: str,
                  device, quick: bool) -> list[F.FeatureResult]:
    if gate_bins < 1:
        raise SignaturesError(f"gate_bins must be >= 1, got {gate_bins}")
    if domain not in DOMAINS:
        raise SignaturesError(f"unknown domain {domain!r} (known: {', '.join(DOMAINS)})")
    if iq.shape[0] == 0:
        return []
    if not (np.issubdtype(iq.dtype, np.number) and not np.issubdtype(iq.dtype, np.timedelta64)):
        raise SignaturesError(f"IQ cube must be numeric, got dtype {iq.dtype}")
    n_chirps, n_bins = iq.shape[1:]
    config = configs[0]
    within = [_Chosen(e, configs[b], gate_bins, n_bins, labels[b], domain) if callable(e)
              else _within(configs[b], e, gate_bins, n_bins, labels[b], domain) for b, e in enumerate(expected)]
    cube = _cube_stage(iq, within, gate_bins, suppress, domain, labels, fft_backend, device)
    live = np.flatnonzero(~cube.zero)
    results: list[F.FeatureResult | None] = [None] * iq.shape[0]
    for b in np.flatnonzero(cube.zero):
        results[b] = F.empty(config, n_chirps, n_bins, within[b])
    if live.size:
        offsets = np.array([configs[b].range_offset_m for b in live])
        window = 0 if quick else flash_series.subchirp_window(config, n_bins, domain)
        sub = _subchirp_bins(iq, live, cube.peak_bin[live], cube.log2_scale[live], labels, window) if window else None
        for b, r in zip(live, _slow_stage(cube, live, config, offsets, n_chirps, n_bins, suppress,
                                          fft_backend, domain, quick, sub, window)):
            results[b] = r
    return results  # type: ignore[return-value]


def _within(config: RadarConfig, expected: float | None, gate_bins: int, n_bins: int,
            label: int, domain: str) -> tuple[int, int] | None:
    """The gate an expected range asks for (see `extract_iq`), or None."""
    if expected is None:
        return None
    if domain == "cw":
        raise RowError(label, "a CW recording measures no range: an expected range cannot gate it")
    lo, hi = config.range_window_m
    if not (math.isfinite(expected) and lo <= expected < hi):
        raise RowError(label, f"expected range {expected:g} m is outside the recorded window [{lo:g}, {hi:g}) m")
    k = int((expected - lo) / config.range_bin_m(n_bins))
    return max(0, k - gate_bins // 2), min(n_bins, k + gate_bins // 2 + 1)


#: Picks the range (m) to gate a return at from its targets (`detections`: (range m, SNR dB),
#: strongest first), or None for the strongest target of the window: an `expected_range_m`
#: entry the cube stage answers from the row's own range profile (no second range FFT).
Chooser = Callable[[list[tuple[float, float]]], "float | None"]


class _Chosen:
    """A row's gate chosen by a `Chooser` once the cube stage has its range profile."""

    def __init__(self, choose: Chooser, config: RadarConfig, gate_bins: int, n_bins: int, label: int,
                 domain: str) -> None:
        self.choose, self.config, self.gate_bins, self.n_bins = choose, config, gate_bins, n_bins
        self.label, self.domain = label, domain

    def __call__(self, profile: np.ndarray | None, hits: np.ndarray) -> tuple[int, int] | None:
        """The gate for the row's profile and its CFAR hits (profile None: an all-zero row, which
        has no targets)."""
        found = [] if profile is None or self.domain == "cw" else _targets(profile, hits, self.config)
        with _own_workspaces():  # the chooser may extract features itself (authn.association)
            expected = self.choose(found)
        return _within(self.config, expected, self.gate_bins, self.n_bins, self.label, self.domain)


@contextlib.contextmanager
def _own_workspaces():
    """Fresh per-thread workspaces (`_scratch`) for a nested extraction, the caller's kept intact."""
    kept = getattr(_local, "spaces", None)
    _local.spaces = {}
    try:
        yield
    finally:
        _local.spaces = kept


# --- cube stage ---------------------------------------------------------------------------------

def _cube_stage(iq: np.ndarray, within: list, gate_bins: int, suppress: bool,
                domain: str, labels: list[int], fft_backend: str, device=None) -> _Cube:
    """Scale, suppress clutter, range-FFT, profile and detect in cache-sized blocks of rows (on
    `fft_backend`, or in torch on `device`); keep each row's gate and patch columns. `within`:
    each row's detection window, or a `_Chosen` replaced in place by the window it chooses."""
    n_rows, n_chirps, n_bins = iq.shape
    size = min(gate_bins, n_bins)
    p_size = min(F.PATCH_SHAPE[1], n_bins)
    looks = max(1, n_chirps - 1) if suppress else n_chirps
    out = dict(log2_scale=np.zeros(n_rows, int), zero=np.zeros(n_rows, bool),
               profile=np.zeros((n_rows, n_bins), np.float32), mu=np.zeros((n_rows, n_bins), np.complex64),
               detected=np.zeros(n_rows, bool), peak_bin=np.zeros(n_rows, int),
               peak_bin_frac=np.zeros(n_rows), snr_db=np.zeros(n_rows), gate_lo=np.zeros(n_rows, int),
               slow=np.empty((n_rows, n_chirps, size), np.complex64), patch_lo=np.zeros(n_rows, int))
    patch_cols = None if device is None else np.empty((n_rows, n_chirps, p_size), np.complex64)
    block = max(1, _CUBE_BLOCK_BYTES // ((16 if fft_backend == "numpy" else 8) * n_chirps * n_bins))
    group = max(1, _SPECTRA_BYTES // (8 * n_chirps * n_bins) // block) * block
    for s in range(0, n_rows, group):  # detection and gating once per group of blocks
        e = min(n_rows, s + group)
        if device is None:
            spectra = _scratch("spectra", (e - s, n_chirps, n_bins), np.complex64)
            for b0 in range(s, e, block):
                b1 = min(e, b0 + block)
                spec = spectra[b0 - s:b1 - s]
                (out["mu"][b0:b1], out["log2_scale"][b0:b1], out["zero"][b0:b1],
                 out["profile"][b0:b1]) = _range_spectra(_block(iq, b0, b1), suppress, domain, labels[b0:b1], spec,
                                                         fft_backend)
            columns = _row_columns
        else:
            from signatures.dsp import torch_cube

            spectra, out["mu"][s:e], out["log2_scale"][s:e], out["zero"][s:e], out["profile"][s:e] = (
                torch_cube.range_spectra(iq[s:e], suppress, domain, labels[s:e], device))
            columns = torch_cube.columns
        hits, threshold = _cfar(out["profile"][s:e], looks)
        for b in range(s, e):  # gates chosen from the rows' own targets: chosen now
            if isinstance(within[b], _Chosen):
                within[b] = within[b](None if out["zero"][b] else out["profile"][b], hits[b - s])
        lo_w = np.array([w[0] if w else 0 for w in within[s:e]])
        hi_w = np.array([w[1] if w else n_bins for w in within[s:e]])
        det, frac, snr, peak = _detect(out["profile"][s:e], hits, threshold, looks, lo_w, hi_w)
        g_lo = _window(peak, size, n_bins)
        p_lo = _window(peak, p_size, n_bins)
        columns(spectra, g_lo, size, out["slow"][s:e])
        if patch_cols is not None:
            columns(spectra, p_lo, p_size, patch_cols[s:e])
        for key, val in (("detected", det), ("peak_bin", peak), ("peak_bin_frac", frac), ("snr_db", snr),
                         ("gate_lo", g_lo), ("patch_lo", p_lo)):
            out[key][s:e] = val
    if patch_cols is not None:
        patch_row = patch_cols.__getitem__
    else:
        patch_row = _PatchColumns(iq, out["patch_lo"], p_size, suppress, domain, labels, fft_backend)
    return _Cube(**out, patch_row=patch_row)


class _PatchColumns:
    """Row b's CNN patch columns, computed when asked for (`features._patch` runs only when the
    cascade calls the CNN): the row's range spectrum again, by the same functions on that row
    alone, so the same values bit for bit (the single path's; tests/features/test_batch_features.py).
    Keeping them for every row instead cost a (B, chirps, 32) complex64 array per batch (39 MB of
    fresh pages for a `paper` batch of 256) and its gather. Holds the input rows: a caller that
    writes into its IQ array before building a patch gets the patch of what it wrote."""

    def __init__(self, iq: np.ndarray | _Stack, lo: np.ndarray, size: int, suppress: bool, domain: str,
                 labels: list[int], fft_backend: str) -> None:
        self.iq, self.lo, self.size = iq, lo, size
        self.suppress, self.domain, self.labels, self.fft_backend = suppress, domain, labels, fft_backend

    def __call__(self, b: int) -> np.ndarray:
        row = np.asarray(self.iq[b])[None]
        spectrum = np.empty(row.shape, np.complex64)
        _range_spectra(row, self.suppress, self.domain, [self.labels[b]], spectrum, self.fft_backend)
        lo = int(self.lo[b])
        return spectrum[0, :, lo:lo + self.size].copy()


def _range_spectra(a: np.ndarray, suppress: bool, domain: str, labels: list[int], out: np.ndarray,
                   fft_backend: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`rd.prepare`, `features._range_spectrum` and `rd.range_profile` of every row with the
    single path's arithmetic on `fft_backend`: the complex64 spectrum into `out`; returns (mu
    (the spectrum of the slow-time mean, complex64), log2 scale, all-zero flag, profile)."""
    x, scale, exponent, zero = prepared(a, labels)
    if fft_backend == "scipy":
        mu, profile = _spectra32(x, scale, suppress, domain, out)
    else:
        mu = _spectra64(x, scale, suppress, domain, out)
        profile = _range_profile(out)
    return mu, exponent, zero, profile


def _spectra64(x: np.ndarray, scale: np.ndarray, suppress: bool, domain: str, out: np.ndarray) -> np.ndarray:
    """The numpy backend's range spectra (`signatures.dsp.fft`: complex128 transforms of the
    complex64 data times the float64 window, rounded to complex64) into `out`; returns mu.
    Chirps run in chunks (`_CHUNK_BYTES`) to bound the complex128 workspaces on big cubes."""
    mean = x.mean(axis=1, keepdims=True)
    n_chirps, n_bins = x.shape[1:]
    weight = scale * (rd.hann(n_bins) if domain == "if" else 1.0)  # (rows, 1, bins): exact products
    mu = mean[:, 0] * weight[:, 0]
    step = max(1, _CHUNK_BYTES // (16 * x.shape[0] * n_bins))
    for c0 in range(0, n_chirps, step):
        part = x[:, c0:c0 + step]
        y = np.subtract(part, mean, out=_scratch("y", part.shape, np.complex64)) if suppress else part
        src = np.multiply(y, weight, out=_scratch("in", part.shape, np.complex128))
        if domain != "if":  # a range cube already is a range spectrum
            np.copyto(out[:, c0:c0 + step], src, casting="same_kind")
            continue
        spec = np.fft.fft(src, axis=-1, out=_scratch("out", part.shape, np.complex128))
        np.copyto(out[:, c0:c0 + step], spec, casting="same_kind")  # the single path's complex64 spectrum
    if domain != "if":
        return mu.astype(np.complex64)
    return np.fft.fft(mu, axis=-1).astype(np.complex64)


def _spectra32(x: np.ndarray, scale: np.ndarray, suppress: bool, domain: str,
               out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The scipy backend's range spectra (`signatures.dsp.fft`: complex64 data times the float32
    window, single-precision pocketfft) into `out`, in three in-place passes over it (subtract,
    window, transform), and their range profile; returns (mu, profile). Same values as the
    single path with `fft_backend='scipy'`, bit for bit. (Chunks of chirps kept in cache through
    all passes measured 5-10 % slower: the passes are not memory-bound here.)"""
    import scipy.fft as sfft

    mean = x.mean(axis=1, keepdims=True)
    n_bins = x.shape[2]
    window = rd.hann(n_bins).astype(np.float32) if domain == "if" else np.ones(n_bins, np.float32)
    weight = window * scale.astype(np.float32)  # (rows, 1, bins): exact products
    weighted = domain == "if" or bool(np.any(scale != 1.0))
    if suppress:
        np.subtract(x, mean, out=out)
        if weighted:
            np.multiply(out, weight, out=out)
    elif weighted:
        np.multiply(x, weight, out=out)
    else:
        np.copyto(out, x)
    mu = mean[:, 0] * weight[:, 0]
    if domain != "if":  # a range cube already is a range spectrum
        return mu, _range_profile(out)
    _fft_in_place(out, -1)
    return sfft.fft(mu, axis=-1, workers=_fft.SCIPY_WORKERS), _range_profile(out)


def _fft_in_place(a: np.ndarray, axis: int) -> np.ndarray:
    """scipy's FFT of complex64 `a` along `axis`, written into `a` (overwrite_x; copied back
    should scipy decline): no fresh cube-sized array."""
    import scipy.fft as sfft

    res = sfft.fft(a, axis=axis, overwrite_x=True, workers=_fft.SCIPY_WORKERS)
    if not np.may_share_memory(res, a):
        a[...] = res
    return a


def _row_columns(spectra: np.ndarray, lo: np.ndarray, size: int, out: np.ndarray) -> None:
    """spectra[b, :, lo[b]:lo[b] + size] of every row b into `out` (the spectra are a workspace)."""
    for b in range(spectra.shape[0]):
        out[b] = spectra[b, :, lo[b]:lo[b] + size]


def _scratch(key: str, shape: tuple[int, ...], dtype: type) -> np.ndarray:
    """A per-thread array reused across blocks and calls (grown, never shrunk): fresh large
    arrays cost page faults (signatures/dsp/fft.py)."""
    spaces = getattr(_local, "spaces", None)
    if spaces is None:
        spaces = _local.spaces = {}
    size = math.prod(shape)
    buf = spaces.get((key, np.dtype(dtype).str))
    if buf is None or buf.size < size:
        buf = spaces[(key, np.dtype(dtype).str)] = np.empty(size, dtype=dtype)
    return buf[:size].reshape(shape)


def _fft_rows(x: np.ndarray, axis: int, window: np.ndarray, key: str, fft_backend: str,
              post=None) -> np.ndarray:
    """`signatures.dsp.fft.fft(x[b], axis - 1, window, backend=fft_backend)` of every row b
    (complex64, same arithmetic), in cache-sized blocks of rows through reused workspaces;
    `post` maps each block's transform to what is kept (default: the transform itself)."""
    step = max(1, _CUBE_BLOCK_BYTES // (16 * max(1, math.prod(x.shape[1:]))))
    parts = []
    for s in range(0, x.shape[0], step):
        blk = x[s:s + step]
        if fft_backend == "scipy":
            spec = np.multiply(blk, window.astype(np.float32), out=_scratch(key + "64", blk.shape, np.complex64))
            _fft_in_place(spec, axis)
        else:
            src = np.multiply(blk, window, out=_scratch(key + "in", blk.shape, np.complex128))
            out = np.fft.fft(src, axis=axis, out=_scratch(key + "out", blk.shape, np.complex128))
            spec = _scratch(key + "64", blk.shape, np.complex64)
            np.copyto(spec, out, casting="same_kind")
        parts.append(post(spec) if post is not None else spec.copy())
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def _range_profile(spec: np.ndarray) -> np.ndarray:
    """`rd.range_profile` per row: mean power over chirps of each range bin (float32; einsum
    accumulates as `rd.range_profile`'s sum over chirps, bit for bit, without its temporary)."""
    b, n, k = spec.shape
    f = spec.view(np.float32).reshape(b, n, 2 * k)
    sq = np.einsum("bnj,bnj->bj", f, f).reshape(b, k, 2).sum(axis=2)
    return (sq / np.float32(n)).astype(np.float32, copy=False)


def _cfar(profile: np.ndarray, looks: int) -> tuple[np.ndarray, np.ndarray]:
    """`rd.cfar` per row (median CFAR over range), the same values: (hits, threshold), (B, bins)."""
    n = profile.shape[1]
    g, t = rd.CFAR_GUARD, rd.CFAR_TRAIN
    offsets = np.concatenate([np.arange(-g - t, -g), np.arange(g + 1, g + t + 1)])
    idx = np.arange(n)[:, None] + offsets[None, :]
    period = max(2 * n - 2, 1)
    idx = np.mod(idx, period)
    idx = np.where(idx >= n, period - idx, idx)
    noise = median_last(profile[:, idx]).astype(np.float32, copy=False)
    factor = rd._cfar_factor(looks, offsets.size, rd.CFAR_PFA)
    threshold = noise * np.float32(factor)
    return (profile > threshold) & (profile > rd._TINY), threshold


def _detect(profile: np.ndarray, hits: np.ndarray, threshold: np.ndarray, looks: int, lo: np.ndarray,
            hi: np.ndarray):
    """`rd.detect` per row from its `_cfar` (detection counted within [lo, hi)):
    (detected, peak_bin_frac, snr_db, peak_bin)."""
    b, n = profile.shape
    t = rd.CFAR_TRAIN
    cols = np.arange(n)[None, :]
    sel = (cols >= lo[:, None]) & (cols < hi[:, None])
    region = hits & sel
    level = np.maximum(threshold / np.float32(rd._cfar_factor(looks, 2 * t, rd.CFAR_PFA)), rd._TINY)
    ratio = np.where(sel, profile / level, -np.inf)
    any_hit = region.any(axis=1)
    ratio = np.where(any_hit[:, None] & ~region, -np.inf, ratio)
    k = np.argmax(ratio, axis=1)
    best = ratio[np.arange(b), k].astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        snr = np.where(np.isfinite(best), 10.0 * np.log10(np.maximum(best, 1e-30)), -300.0)
    return any_hit, _interp_peak(profile, k), snr, k


def _interp_peak(y: np.ndarray, k: np.ndarray) -> np.ndarray:
    """`rd._interp_peak` per row: log-parabolic sub-bin peak of y[b] around k[b]."""
    b, n = y.shape
    if n < 3:
        return k.astype(np.float64)
    inner = (k > 0) & (k < n - 1)
    kc = np.clip(k, 1, n - 2)  # edge rows keep k (below); clipped only to index safely
    rows = np.arange(b)
    a, m, c = (np.log(np.maximum(y[rows, kc + j].astype(np.float64), 1e-37)) for j in (-1, 0, 1))
    den = a - 2.0 * m + c
    with np.errstate(divide="ignore", invalid="ignore"):
        step = np.clip(0.5 * (a - c) / np.where(den < 0.0, den, -1.0), -0.5, 0.5)
    return np.where(inner & (den < 0.0), k + step, k.astype(np.float64))


def _window(centre: np.ndarray, size: int, n: int) -> np.ndarray:
    """`features._window` per row: the window's first bin."""
    return np.minimum(np.maximum(0, centre - size // 2), n - size)


def _columns(x: np.ndarray, lo: np.ndarray, size: int) -> np.ndarray:
    """x[b, :, lo[b]:lo[b] + size] for every row b (one slice per distinct lo: most rows share
    the gate's centre)."""
    values = distinct(lo)
    if len(values) == 1:
        return x[:, :, int(values[0]):int(values[0]) + size].copy()
    out = np.empty(x.shape[:2] + (size,), x.dtype)
    for v in values:
        sel = np.flatnonzero(lo == v)
        out[sel] = x[sel, :, v:v + size]
    return out


# --- slow-time stage -----------------------------------------------------------------------------

def _subchirp_bins(iq: np.ndarray | _Stack, rows: np.ndarray, peak_bin: np.ndarray, log2_scale: np.ndarray,
                   labels: list[int], window: int) -> np.ndarray:
    """`flash_series.subchirp_bins` of the prepared rows `rows` at their peak bins, (rows, chirps,
    windows, bins), with the single path's products (`flash_series.scaled_subchirp_basis`).
    `rd.prepare`'s power-of-two scale (the cube stage's `log2_scale`) rides on the basis, which
    is exact; a row that `prepared` would scale itself (not complex64, or beyond its safe
    exponent) goes through it. With BLAS on one thread the rows that share a peak bin and a
    scale are stacked into one product (`_stacked_subchirp_bins`; the same values to float32
    rounding: a BLAS kernel may order its sums by the product's height), else each row makes
    its own."""
    n_chirps = iq.shape[1]
    out = np.empty((rows.size, n_chirps, flash_series.SUBCHIRP_WINDOWS, flash_series.SUBCHIRP_BINS), np.complex64)
    stack = blas_on_one_thread()
    shared: dict[tuple[int, int], list[int]] = {}
    for j, b in enumerate(rows.tolist()):
        row = np.asarray(iq[b])
        exponent = int(log2_scale[j])
        if row.dtype == np.complex64 and abs(exponent) <= SAFE_EXPONENT:
            if stack:
                shared.setdefault((int(peak_bin[j]), exponent), []).append(j)
                continue
            x, s = row, math.ldexp(1.0, -exponent)
        else:
            xs, scale, _, _ = prepared(row[None], [labels[b]])
            x, s = xs[0], float(scale[0, 0, 0])
        out[j] = flash_series.subchirp_bins(x, int(peak_bin[j]), window, s)
    for (peak, exponent), js in shared.items():
        _stacked_subchirp_bins(iq, rows[js], np.asarray(js), peak, math.ldexp(1.0, -exponent), window, out)
    return out


def _stacked_subchirp_bins(iq: np.ndarray | _Stack, rows: np.ndarray, at: np.ndarray, peak_bin: int,
                           scale: float, window: int, out: np.ndarray) -> None:
    """The sub-chirp bins of complex64 rows `rows` sharing a peak bin and a scale into `out[at]`:
    cache-sized blocks of rows stacked into one (rows x chirps, samples) product each."""
    n_chirps, n_samples = iq.shape[1:]
    basis = flash_series.scaled_subchirp_basis(n_samples, peak_bin, window, np.complex64, scale)
    step = max(1, _CUBE_BLOCK_BYTES // (8 * n_chirps * n_samples))
    for s in range(0, rows.size, step):
        part = rows[s:s + step].tolist()
        x = np.stack([iq[b] for b in part], out=_scratch("subchirp", (len(part), n_chirps, n_samples), np.complex64))
        prod = np.matmul(x.reshape(-1, n_samples), basis,
                         out=_scratch("subchirp_out", (len(part) * n_chirps, basis.shape[1]), np.complex64))
        out[at[s:s + step]] = prod.reshape((len(part), n_chirps) + out.shape[2:])


def _slow_stage(cube: _Cube, live: np.ndarray, config: RadarConfig, offsets: np.ndarray, n_chirps: int,
                n_bins: int, suppress: bool, fft_backend: str, domain: str, quick: bool,
                sub: np.ndarray | None = None, window: int = 0) -> list[F.FeatureResult]:
    """The features of the rows `live` (not all-zero; range offsets `offsets`) from their
    slow-time gates; `sub`: their sub-chirp bins of `window` samples, where the waveform has them."""
    slow = cube.slow[live]
    gate = _gate_power(cube, live, slow, n_chirps, suppress, domain, fft_backend)
    d = flash_series.sum_last_axis(gate.power)  # power.sum(axis=2) to the bit (bins left to right), ~8x faster
    line = _line(d, flash_series.sum_last_axis(gate.raw_power), slow, gate.stationary, config, suppress, domain)
    cols, body_hz = _moment_columns(cube, live, config, offsets, n_bins, domain, gate, d, line)
    long_dwell = not quick and n_chirps * config.pri_s >= flash_spectrum.SPECTRAL_DWELL_S
    if quick:
        return _results(cube, live, config, fft_backend, cols, line.body_idx, None, long_dwell)
    rotors = _flash_columns(cube, live, slow, config, n_bins, fft_backend, domain, sub, window, body_hz,
                            long_dwell, cols)
    return _results(cube, live, config, fft_backend, cols, line.body_idx, rotors, long_dwell)


class _GatePower(NamedTuple):
    """The slow-time gates' Doppler power (rows, Doppler bins, gate bins), before clutter
    suppression too, the stationary power suppression removed, and detection in the gate."""

    power: np.ndarray
    raw_power: np.ndarray
    stationary: np.ndarray
    noise_bin: np.ndarray  # mean noise power per chirp in a range bin
    noise_doppler: np.ndarray  # noise power per Doppler bin
    detected: np.ndarray
    snr_db: np.ndarray


def _gate_power(cube: _Cube, live: np.ndarray, slow: np.ndarray, n: int, suppress: bool, domain: str,
                fft_backend: str) -> _GatePower:
    """The gates' Doppler spectra and noise levels; a CW channel detects on its Doppler bins."""
    dop = _fft_rows(slow, 1, rd.hann(n)[:, None], "doppler", fft_backend, lambda z: np.fft.fftshift(z, axes=1))
    power = _power(dop)
    if suppress:
        raw_power, stationary = _unsuppressed(cube.mu[live], dop, power, cube.gate_lo[live], slow.shape[2])
    else:
        raw_power, stationary = power, np.zeros(live.size)
    noise_bin = median_last(cube.profile[live]).astype(np.float64)  # mean noise power per chirp in a bin
    if domain == "cw":  # one channel: the Doppler bins are the reference cells
        noise_doppler = np.maximum(median_last(power[:, :, 0]).astype(np.float64), _TINY)
        detected, snr_db = _cw_detection(power[:, :, 0], cube.profile[live, 0], noise_doppler)
    else:
        noise_doppler = np.maximum(noise_bin * n * float(np.mean(rd.hann(n) ** 2)), _TINY)
        detected, snr_db = cube.detected[live], cube.snr_db[live]
    return _GatePower(power, raw_power, stationary, noise_bin, noise_doppler, detected, snr_db)


class _Line(NamedTuple):
    """The body's Doppler line per row: its bin, its spread in bins, and whether it hovers."""

    body_idx: np.ndarray
    vel_std_bins: np.ndarray
    hovering: np.ndarray


def _line(d: np.ndarray, d_raw: np.ndarray, slow: np.ndarray, stationary: np.ndarray, config: RadarConfig,
          suppress: bool, domain: str) -> _Line:
    """Find the body's line in the Doppler power `d` (`d_raw`: before clutter suppression)."""
    n = d.shape[1]
    centre = n // 2
    d_max = d.max(axis=1).astype(np.float64)
    d_med = median_last(d).astype(np.float64)
    contrast = d_max / np.maximum(d_med, _TINY)
    # a CW channel has no other range bins to tell clutter from a body at zero Doppler: without a
    # narrow moving line, the body is the one clutter suppression removed there
    peak = np.argmax(d, axis=1)
    if domain == "cw":  # ... and a line that the micro-Doppler is not symmetric about is a rotor's
        off, stands_out, unmirrored, reach = _off_clutter_line(d, d_med, centre, config.pri_s)
        drifting, drift_idx = _drifting_line(slow, off, reach, unmirrored & ~stands_out & suppress)
        flying = suppress & unmirrored & (stands_out | drifting)
        peak = np.where(flying, off, peak)
        hovering = suppress & ~flying & ((contrast < n / F.MOVING_LINE_BINS)
                                         | (_symmetry(d, np.full(d.shape[0], centre)) >= _symmetry(d, peak)))
    else:
        hovering = suppress & (stationary > d_max) & (contrast < n / F.MOVING_LINE_BINS)
    body_idx, vel_std_bins = _body_line(d, d_raw, d_med, centre, hovering, peak)
    if domain == "cw":  # an accelerating body's line, followed over sub-dwells: its mid-dwell Doppler
        body_idx = np.where(drifting, drift_idx, body_idx)
    return _Line(body_idx, vel_std_bins, hovering)


def _moment_columns(cube: _Cube, live: np.ndarray, config: RadarConfig, offsets: np.ndarray, n_bins: int,
                    domain: str, gate: _GatePower, d: np.ndarray,
                    line: _Line) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The features every row has, quick or not (range, velocity, the gate's spectral moments,
    peaks, entropy, tip speed, detection), and the body's Doppler (Hz) the flash stage reads."""
    n, size = d.shape[1], cube.slow.shape[2]
    power, peak_bin, g_lo, body_idx = gate.power, cube.peak_bin[live], cube.gate_lo[live], line.body_idx
    bin_m = config.range_bin_m(n_bins)
    dop_bin_hz = config.prf_hz / n
    lam = config.doppler_wavelength_m(n_bins)
    body_hz = (body_idx - n // 2) * dop_bin_hz
    velocity = body_hz * lam / 2.0
    vel_std = line.vel_std_bins * dop_bin_hz * lam / 2.0
    dwell = n * config.pri_s
    snr = np.maximum(10.0 ** (gate.snr_db / 10.0), 1e-3)
    range_mid = offsets + cube.peak_bin_frac[live] * bin_m
    hover_bin = F.hover_range_bin(cube.profile[live], peak_bin, gate.noise_bin)
    range_est = np.where(line.hovering, offsets + hover_bin * bin_m, range_mid)
    range_std = bin_m * (0.05 + 1.0 / np.sqrt(snr))

    rel_bins = np.mod(np.arange(n)[None, :] - body_idx[:, None] + n // 2, n) - n // 2
    rel_hz = (rel_bins * dop_bin_hz).astype(np.float32)
    total = np.maximum(d.sum(axis=1).astype(np.float64), _TINY)
    total32 = total.astype(np.float32)[:, None]
    q_d = d / total32
    q_r = power.sum(axis=1) / total32
    r_axis = (g_lo[:, None] + np.arange(size) - peak_bin[:, None]) * bin_m
    mu_r_rel = np.sum(r_axis * q_r, axis=1)
    std_r = np.sqrt(np.maximum(np.sum((r_axis - mu_r_rel[:, None]) ** 2 * q_r, axis=1), 0.0))
    mu_hz = np.sum(rel_hz * q_d, axis=1).astype(np.float64)
    dev = rel_hz - mu_hz.astype(np.float32)[:, None]
    std_hz = np.sqrt(np.maximum(np.sum(dev ** 2 * q_d, axis=1).astype(np.float64), 0.0))
    d_max = d.max(axis=1).astype(np.float64)
    par_db = _db(d_max / np.maximum(d.mean(axis=1).astype(np.float64), _TINY))
    micro = np.abs(rel_bins) > F.BODY_BINS
    d_micro = np.where(micro, d, np.float32(0.0))
    micro_power = np.maximum(d_micro.sum(axis=1).astype(np.float64), _TINY)
    abs_hz = np.abs(rel_hz)
    centroid = np.sum(abs_hz * d_micro, axis=1).astype(np.float64) / micro_power
    spread = np.where(micro, (abs_hz - centroid.astype(np.float32)[:, None]) ** 2 * d, np.float32(0.0))
    bandwidth = np.sqrt(np.maximum(spread.sum(axis=1).astype(np.float64) / micro_power, 0.0))
    peak_db = _db(power.max(axis=(1, 2)).astype(np.float64)) + 20.0 * math.log10(2.0) * cube.log2_scale[live]
    noise_gate = gate.noise_doppler * size
    shift = (n // 2 - body_idx).astype(int)  # np.roll's truncation of a fractional shift
    rolled = np.take_along_axis(d, (np.arange(n)[None, :] - shift[:, None]) % n, axis=1)
    n_peaks = _count_peaks(rolled, noise_gate)
    energy_ratio = np.where(micro, np.float32(0.0), d).sum(axis=1).astype(np.float64) / total
    q = power / total32[:, :, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        plogp = np.where(q > 0, q * np.log(np.maximum(q, np.float32(_TINY))), np.float32(0.0))
    entropy = -plogp.reshape(live.size, -1).sum(axis=1).astype(np.float64) / math.log(max(n * size, 2))

    occupied = _smooth(d, max(1, n // 256)) > (noise_gate * 10 ** (F.OCCUPANCY_DB / 10)).astype(np.float32)[:, None]
    tip, tip_std, aliased = _tip_speed(occupied, rel_bins, body_hz, config, dop_bin_hz)
    cols = dict(
        mean_range_m=range_mid + mu_r_rel, mean_doppler_mps=velocity + mu_hz * lam / 2.0,
        std_range_m=std_r, std_doppler_mps=std_hz * lam / 2.0, par_db=par_db,
        spectral_centroid_hz=centroid, spectral_bandwidth_hz=bandwidth, peak_amplitude_db=peak_db,
        num_peaks=n_peaks, energy_ratio=energy_ratio, entropy=entropy,
        range_m=range_est - velocity * dwell / 2.0, range_std_m=range_std,
        radial_velocity_mps=velocity, radial_velocity_std_mps=vel_std,
        tip_speed_mps=tip, tip_speed_std_mps=tip_std, tip_aliased=aliased, doppler_occupancy=occupied.mean(axis=1),
        snr_db=np.maximum(gate.snr_db, -100.0), detected=gate.detected)
    if domain == "cw":  # no range measured: range features are 0 by definition (docs/features.md)
        for name in ("mean_range_m", "std_range_m", "range_m", "range_std_m"):
            cols[name] = np.zeros(live.size)
    return cols, body_hz


class _Rotors(NamedTuple):
    """The rotors a row's flashes show (`feature_vector.physics_estimates`): seen, its spread,
    and whether the count is known (not only a lower bound)."""

    seen: np.ndarray
    seen_std: np.ndarray
    known: np.ndarray
    #: a long dwell's score at every candidate rate (rows, candidates) and the candidates (Hz)
    curve: np.ndarray | None = None
    curve_hz: np.ndarray | None = None


def _flash_columns(cube: _Cube, live: np.ndarray, slow: np.ndarray, config: RadarConfig, n_bins: int,
                   fft_backend: str, domain: str, sub: np.ndarray | None, window: int, body_hz: np.ndarray,
                   long_dwell: bool, cols: dict[str, np.ndarray]) -> _Rotors:
    """Add the blade-flash features to `cols` (rate, rotors, blade length, cadence, envelope);
    a long dwell's hundreds of flashes: the envelope spectrum resolves the rate, and counts the
    rotors visible."""
    size, bin_m = slow.shape[2], config.range_bin_m(n_bins)
    peak_bin, g_lo = cube.peak_bin[live], cube.gate_lo[live]
    if sub is not None:
        series = flash_series.flash_series_batch(sub, config, body_hz, bin_m * n_bins / window, window)
        per = flash_period.periodicity_batch(series)
    else:
        per = _flash(slow, peak_bin - g_lo, config, body_hz, bin_m, n_bins)
    flash, flash_std, score = per.flash_rate_hz, per.flash_rate_std_hz, per.score
    rotors = _Rotors(per.rotors_seen, per.rotors_seen_std, np.ones(live.size, dtype=bool))
    width = int(min(3, size))  # the target's bin +- 1, inside the gate
    centre_cols = _columns(slow, np.clip(peak_bin - g_lo - 1, 0, size - width), width)
    if long_dwell:
        train = flash_spectrum.spectral_flash_rate(centre_cols, config, body_hz)
        flash, flash_std, score = train.rate_hz, train.rate_std_hz, train.score
        rotors = _Rotors(train.rotors_seen, train.rotors_seen_std,
                         train.rotors_known if train.rotors_known is not None else rotors.known,
                         train.curve, train.curve_hz)
        if domain == "cw":  # a periodic flash train is a target even where no Doppler line stands out
            train_found = score >= flash_spectrum.SPECTRAL_DETECT_SCORE
            cols["detected"] = np.asarray(cols["detected"], dtype=bool) | train_found
    _blade_columns(cols, flash, flash_std, config, long_dwell)
    n = slow.shape[1]
    win, hop = tf.stft_params(config, n)
    cad_peak, cad_ratio = _cadence_features(_cadence(_spectrogram(slow, config, win, hop, fft_backend),
                                                     fft_backend), flash)
    env_win, env_hop = envelope.frames(config, n)
    env_power, _ = _spectrogram(centre_cols, config, env_win, env_hop, fft_backend)
    cols.update(zip(F.ENVELOPE_FEATURES, envelope.from_spectrogram(env_power, config, body_hz, env_hop).T))
    cols.update(
        flash_rate_hz=flash, flash_rate_std_hz=flash_std, rotor_count=per.rotor_count,
        rotor_count_std=per.rotor_count_std, flash_score=score, flash_count=per.n_events,
        flash_par_db=per.flash_par_db, cadence_peak_hz=cad_peak, cadence_harmonic_ratio=cad_ratio)
    return rotors


def _blade_columns(cols: dict[str, np.ndarray], flash: np.ndarray, flash_std: np.ndarray, config: RadarConfig,
                   long_dwell: bool) -> None:
    """Add the rotor rate (the flash rate over `flash_period.BLADES_ASSUMED`) and the blade length (tip speed
    over 2 pi times the rotor rate) to `cols`; a long dwell reads the tip to within one rotor line."""
    tip, tip_std, aliased = cols["tip_speed_mps"], cols["tip_speed_std_mps"], cols["tip_aliased"]
    rotor, rotor_std = flash / flash_period.BLADES_ASSUMED, flash_std / flash_period.BLADES_ASSUMED
    if long_dwell:  # the tip's extent is read to within one of the rotor's lines (`tip_line_std`)
        tip_std = np.where(aliased, tip_std, np.hypot(tip_std, tip_line_std(rotor, config.wavelength_m)))
        cols["tip_speed_std_mps"] = tip_std
    has_length = (rotor > 0) & (tip > 0) & ~aliased  # a lower-bound tip gives no length
    with np.errstate(divide="ignore", invalid="ignore"):
        length = np.where(has_length, tip / (2 * math.pi * rotor), 0.0)
        length_std = np.where(has_length, length * np.hypot(tip_std / tip, rotor_std / rotor), 0.0)
    cols.update(rotor_rate_hz=rotor, rotor_rate_std_hz=rotor_std, blade_length_m=length,
                blade_length_std_m=length_std)


def _results(cube: _Cube, live: np.ndarray, config: RadarConfig, fft_backend: str, cols: dict[str, np.ndarray],
             body_idx: np.ndarray, rotors: _Rotors | None, long_dwell: bool) -> list[F.FeatureResult]:
    """One FeatureResult per live row: its features (0 where `cols` has none), gate, and, unless
    quick (`rotors` None), its CNN patch maker and physics estimates."""
    size = cube.slow.shape[2]
    zeros = np.zeros(live.size)
    table = np.stack([np.asarray(cols.get(name, zeros), dtype=np.float64) for name in F.FEATURE_NAMES],
                     axis=1).tolist()
    detected_rows = np.asarray(cols["detected"], dtype=bool).tolist()
    gates = (cube.gate_lo[live] + 0).tolist()
    if rotors is None:
        return [F.FeatureResult(detected_rows[j], F.Features(*table[j]), F.no_patch, (gates[j], gates[j] + size))
                for j in range(live.size)]
    seen_rows, seen_std_rows = np.asarray(rotors.seen).tolist(), np.asarray(rotors.seen_std).tolist()
    known_rows = np.asarray(rotors.known, dtype=bool).tolist()
    out = []
    for j, b in enumerate(live.tolist()):
        make = _patch_maker(cube.patch_row, b, config, int(cube.peak_bin[b] - cube.patch_lo[b]), float(body_idx[j]),
                            fft_backend)
        curve = (None if rotors.curve is None or rotors.curve_hz is None
                 else flash_spectrum.FlashCurve(rotors.curve_hz, rotors.curve[j]))
        out.append(F.FeatureResult(detected_rows[j], F.Features(*table[j]), make, (gates[j], gates[j] + size),
                                   physics=F.physics_estimates(seen_rows[j], seen_std_rows[j], long_dwell,
                                                               known_rows[j]), flash_curve=curve))
    return out


def tip_line_std(rotor_rate_hz: np.ndarray, wavelength_m: float) -> np.ndarray:
    """The LOS speed (m/s) of one line of a rotor's long-dwell Doppler spectrum: the blades repeat
    each turn, so the spectrum is lines f_rot apart (2 f_rot for equal blades), and the last one
    over the occupancy threshold lies within a line of the tip's Doppler 4 pi L f_rot / lambda,
    a share lambda / (4 pi L) of it whatever the rate: 0.3 % for 6 cm blades at 77 GHz, 13 % at
    3.3 GHz, where the held-out world read such tips up to 9 % fast (`cw-idle-*` conditions)."""
    return np.maximum(np.asarray(rotor_rate_hz, dtype=np.float64), 0.0) * wavelength_m / 2.0


def _off_clutter_line(d: np.ndarray, d_med: np.ndarray, centre: int,
                      pri_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """CW rows of Doppler power `d` (fftshifted, zero at `centre`): (the strongest bin outside the
    zero-Doppler line, whether it stands out, whether it is unmirrored, the line's reach in bins by
    `flash_spectrum.line_width_hz`); together they say whether that bin is a flying body's
    line: it stands out as a moving line does (peak over median at least n / MOVING_LINE_BINS) and
    has no mirror image about zero (MIRROR_DB over the strongest of the 5 bins there). Swaying
    clutter (vegetation) 20-40 dB over a target spreads over tens of Hz about zero, outshines the
    body's line and is itself symmetric about zero, and a CW channel has no range cells to tell it
    apart: the strongest bin, or the profile's symmetry, read a flying target as hovering. A
    hovering rotor's lines come in mirror pairs (a blade's Doppler swings both ways in a turn)."""
    rows, n = d.shape
    r = np.arange(rows)
    reach = flash_spectrum.line_width_hz(np.fft.ifftshift(d, axes=1).astype(np.float64), pri_s) * n * pri_s
    outside = np.abs(np.arange(n) - centre)[None, :] > np.ceil(reach)[:, None]
    off = np.argmax(np.where(outside, d, 0), axis=1)
    line = d[r, off].astype(np.float64)
    mirror = (2 * centre - off) % n
    image = np.max(np.stack([d[r, (mirror + j) % n] for j in range(-2, 3)]), axis=0).astype(np.float64)
    stands_out = line >= d_med * (n / F.MOVING_LINE_BINS)
    return off, stands_out, line >= image * 10.0 ** (F.MIRROR_DB / 10.0), reach


def _drifting_line(slow: np.ndarray, off: np.ndarray, reach: np.ndarray,
                   rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per CW row of gate slow time `slow` (rows, n, bins; the Doppler profile's `off` its candidate
    line, fftshifted bins): for the `rows` asked, is it a body line smeared by acceleration, and where
    is it at mid-dwell (fractional full-dwell bin)? A body accelerating at a few m/s^2 sweeps its line
    over tens of Hz in 0.8 s, under a single bin's stand-out, where a rotor's line (a harmonic of its
    rate) stays put. In each of SUB_DWELLS sub-dwells the line is sought within DRIFT_SUB_BINS of the
    candidate, outside the zero-Doppler line's `reach` (full-dwell bins); it is a body's where it
    stands out there (peak over median at least the sub-dwell's length / MOVING_LINE_BINS) in all
    but DRIFT_MISSES of them; its mid-dwell bin is the mean of their peaks."""
    n_rows, n = slow.shape[:2]
    drifting = np.zeros(n_rows, bool)
    at = off.astype(np.float64)
    m = n // F.SUB_DWELLS
    idx = np.flatnonzero(rows)
    if idx.size == 0 or m < 4 * F.DRIFT_SUB_BINS:
        return drifting, at
    part = slow[idx, :m * F.SUB_DWELLS].reshape(idx.size, F.SUB_DWELLS, m, -1)
    spec = np.fft.fftshift(np.fft.fft(part * rd.hann(m)[:, None].astype(np.float32), axis=2), axes=2)
    p = _power(spec).sum(axis=3).astype(np.float64)  # (rows, sub-dwells, m)
    med = np.maximum(median_last(p), _TINY)
    centre_sub = (off[idx] - n // 2) * m / n + m // 2  # the candidate in sub-dwell bins
    window = np.rint(centre_sub)[:, None] + np.arange(-F.DRIFT_SUB_BINS, F.DRIFT_SUB_BINS + 1)[None, :]
    cols = window.astype(int) % m
    near = np.take_along_axis(p, np.broadcast_to(cols[:, None, :], p.shape[:2] + cols.shape[1:]), axis=2)
    reach_sub = np.ceil(reach[idx] * m / n) + 1  # the zero-Doppler line's reach, in sub-dwell bins
    near = np.where((np.abs(window - m // 2) > reach_sub[:, None])[:, None, :], near, 0.0)
    k = np.argmax(near, axis=2)
    peak = np.take_along_axis(near, k[:, :, None], axis=2)[:, :, 0]
    clear = peak >= med * (m / F.MOVING_LINE_BINS)
    drifting[idx] = clear.sum(axis=1) >= F.SUB_DWELLS - F.DRIFT_MISSES
    pos = np.take_along_axis(window, k, axis=1)  # sub-dwell bins
    mean_pos = np.sum(np.where(clear, pos, 0.0), axis=1) / np.maximum(clear.sum(axis=1), 1)
    at[idx] = np.where(drifting[idx], (mean_pos - m // 2) * n / m + n // 2, at[idx])
    return drifting, at


def _symmetry(d: np.ndarray, at: np.ndarray) -> np.ndarray:
    """How symmetric each row's Doppler profile is about bin `at[row]`: the correlation of the log
    profile at +f and -f over BODY_BINS < f <= n / 4 (advancing and retreating blades mirror each
    other about the body line)."""
    n = d.shape[1]
    offsets = np.arange(F.BODY_BINS + 1, max(F.BODY_BINS + 2, n // 4 + 1))
    logd = np.log(np.maximum(d.astype(np.float64), F.TINY))
    rows = np.arange(d.shape[0])[:, None]
    up = logd[rows, (at[:, None] + offsets[None, :]) % n]
    down = logd[rows, (at[:, None] - offsets[None, :]) % n]
    up = up - up.mean(axis=1, keepdims=True)
    down = down - down.mean(axis=1, keepdims=True)
    den = np.sqrt((up ** 2).sum(axis=1) * (down ** 2).sum(axis=1))
    return (up * down).sum(axis=1) / np.maximum(den, F.TINY)


def _cw_detection(line: np.ndarray, mean_power: np.ndarray,
                  noise_doppler: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(detected, SNR dB) of CW rows: one channel, so no range cells to run CFAR over. The
    Doppler bins are the reference cells instead: detected when the strongest Doppler line
    exceeds their median by the median-CFAR factor of one look at `rd.CFAR_PFA`. SNR: mean power
    per pulse over the median Doppler bin's noise per pulse (an overestimate of the noise, hence
    an underestimate of the SNR, when micro-Doppler fills most of the band)."""
    n = line.shape[1]
    factor = rd._cfar_factor(1, n, rd.CFAR_PFA)
    detected = line.max(axis=1).astype(np.float64) > noise_doppler * factor
    noise_pulse = noise_doppler / (n * float(np.mean(rd.hann(n) ** 2)))
    return detected, _db(mean_power.astype(np.float64) / noise_pulse)


def _patch_maker(patch_row: Callable[[int], np.ndarray], b: int, config: RadarConfig, peak: int, body_idx: float,
                 fft_backend: str):
    """The lazy CNN patch of row b: `features._patch` of its patch columns (the same window)."""
    def make() -> np.ndarray:
        return F.patch(patch_row(b), config, peak, body_idx, fft_backend)
    return make


def _power(z: np.ndarray) -> np.ndarray:
    return z.real ** 2 + z.imag ** 2


def _db(x: np.ndarray) -> np.ndarray:
    return 10.0 * np.log10(np.maximum(x, 1e-30))


def _unsuppressed(mu: np.ndarray, dop: np.ndarray, power: np.ndarray, g_lo: np.ndarray,
                  size: int) -> tuple[np.ndarray, np.ndarray]:
    """`features._unsuppressed` per row: the gate's Doppler power before mean removal and the
    stationary excess power."""
    n = dop.shape[1]
    mu2 = _power(mu)
    gate_idx = g_lo[:, None] + np.arange(size)
    excess_bins = np.maximum(np.take_along_axis(mu2, gate_idx, axis=1) - median_last(mu2)[:, None],
                             np.float32(0.0))
    excess = excess_bins.sum(axis=1).astype(np.float64) * n * n
    mu_g = np.take_along_axis(mu, gate_idx, axis=1)
    out = power.copy()
    c = n // 2
    for j, w in ((0, 1.0), (-1, -0.5), (1, -0.5)):
        if 0 <= c + j < n and (j == 0 or n > 2):
            out[:, c + j] = _power(dop[:, c + j] + mu_g * np.float32(n * w))
    return out, excess


def _body_line(d: np.ndarray, d_raw: np.ndarray, d_med: np.ndarray, centre: int,
               hovering: np.ndarray, peak: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: the fractional Doppler index of the body line and its std in bins. The line is at
    `peak` (the strongest bin, or a CW row's line off the clutter's); a hovering row's, and one
    within BODY_BINS of zero Doppler, is read from the spectrum before clutter suppression."""
    rows, n = d.shape
    k = peak
    use_raw = hovering | (np.abs(k - centre) <= F.BODY_BINS)
    lo, hi = max(0, centre - F.BODY_BINS), min(n, centre + F.BODY_BINS + 1)
    k = np.where(use_raw, lo + np.argmax(d_raw[:, lo:hi], axis=1), k)
    src = np.where(use_raw[:, None], d_raw, d)
    src_med = np.where(use_raw, median_last(d_raw).astype(np.float64), d_med)
    frac = _interp_peak(src, k)
    line_snr = src[np.arange(rows), k].astype(np.float64) / np.maximum(src_med, _TINY)
    return frac, 0.05 + 1.0 / np.sqrt(np.maximum(line_snr, 1.0))


def _smooth(x: np.ndarray, half: int) -> np.ndarray:
    """`features._smooth` per row: circular moving average over 2 half + 1 bins."""
    if half < 1:
        return x
    k = np.full(2 * half + 1, 1.0 / (2 * half + 1), dtype=x.dtype)
    padded = np.concatenate([x[:, -half:], x, x[:, :half]], axis=1)
    return np.stack([np.convolve(row, k, mode="valid") for row in padded]).astype(x.dtype, copy=False)


def _count_peaks(d: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """`features._count_peaks` per row (prominence over all candidate x bin pairs at once)."""
    rows, size = d.shape
    group = max(1, size // F.PEAK_PROFILE_BANDS)
    m = (size // group) * group
    pooled = d[:, :m].reshape(rows, -1, group).sum(axis=2)
    with np.errstate(divide="ignore"):
        y = np.log(np.maximum(pooled, np.float32(_TINY))) * F.DB_PER_LN
    floor = (_db(noise * group) + F.PEAK_ABOVE_NOISE_DB).astype(np.float32)
    n = y.shape[1]
    rise = np.ones_like(y, dtype=bool)
    rise[:, 1:] = y[:, 1:] > y[:, :-1]
    fall = np.ones_like(y, dtype=bool)
    fall[:, :-1] = y[:, :-1] >= y[:, 1:]
    r, c = np.nonzero((y >= floor[:, None]) & rise & fall)  # candidates: row, band
    if r.size == 0:
        return np.zeros(rows, dtype=int)
    # features._count_peaks' prominence by range-min/max tables (no candidate x band matrices):
    # the base on each side is the lowest point from the candidate to just before the nearest
    # higher band (those points are all <= the candidate, so the candidate itself may be included)
    lows, highs = _tables(y, np.minimum), _tables(y, np.maximum)
    yc = y[r, c]
    left = c.copy()  # first band of the run ending at c with nothing above yc
    right = c + 1  # one past the last band of the run starting at c
    for k in range(len(highs) - 1, -1, -1):
        step = 1 << k
        go = left - step >= 0
        go[go] = highs[k][r[go], left[go] - step] <= yc[go]
        left[go] -= step
        go = right + step <= n
        go[go] = highs[k][r[go], right[go]] <= yc[go]
        right[go] += step
    base_l = _range_min(lows, r, left, c + 1)
    base_r = _range_min(lows, r, c, right)
    prominent = yc - np.maximum(base_l, base_r) >= F.PEAK_PROMINENCE_DB
    return np.bincount(r[prominent], minlength=rows)


def _tables(y: np.ndarray, op) -> list[np.ndarray]:
    """Sparse table per row: level k holds op over y[:, j:j + 2**k] at column j."""
    out = [y]
    while 2 << (len(out) - 1) <= y.shape[1]:
        half = 1 << (len(out) - 1)
        out.append(op(out[-1][:, :-half], out[-1][:, half:]))
    return out


def _range_min(lows: list[np.ndarray], r: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """min of y[r, lo:hi] (hi > lo) from the sparse min table."""
    k = np.floor(np.log2(hi - lo)).astype(int)
    out = np.empty(r.size, dtype=lows[0].dtype)
    for level in distinct(k):
        sel = k == level
        t = lows[level]
        out[sel] = np.minimum(t[r[sel], lo[sel]], t[r[sel], hi[sel] - (1 << level)])
    return out


def _tip_speed(occupied: np.ndarray, rel_bins: np.ndarray, body_hz: np.ndarray, config: RadarConfig,
               dop_bin_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`features._tip_speed` per row."""
    half = occupied.shape[1] // 2
    ext_pos = np.where(occupied & (rel_bins > 0), rel_bins, 0.0).max(axis=1).astype(int)
    ext_neg = (-np.where(occupied & (rel_bins < 0), rel_bins, 0.0).min(axis=1)).astype(int)
    lam2 = config.wavelength_m / 2.0
    aliased = np.maximum(ext_pos, ext_neg) >= F.ALIAS_FRACTION * half
    tip_hz = 0.5 * (ext_pos + ext_neg) * dop_bin_hz
    std_hz = np.hypot(0.5 * np.abs(ext_pos - ext_neg) * dop_bin_hz, dop_bin_hz)
    tip = np.where(aliased, lam2 * np.maximum(config.prf_hz / 2.0 - np.abs(body_hz), 0.0), lam2 * tip_hz)
    return tip, np.where(aliased, 0.0, lam2 * std_hz), aliased


def _flash(slow: np.ndarray, peak_rel: np.ndarray, config: RadarConfig, body_hz: np.ndarray,
           bin_m: float, n_bins: int) -> flash_period.PeriodicityBatch:
    """The blade-flash estimators on each row's peak bin +- 1 (narrower at the gate's edge):
    `signatures.dsp.flash_series` and `signatures.dsp.flash_period` once per column count."""
    size = slow.shape[2]
    lo = np.maximum(0, peak_rel - 1)
    width = np.minimum(size, peak_rel + 2) - lo
    rows = slow.shape[0]
    fields = {name: np.zeros(rows, dtype=int if name == "n_events" else np.float64)
              for name in (f.name for f in dataclass_fields(flash_period.PeriodicityBatch))}
    for w in distinct(width):
        sel = np.flatnonzero(width == w)
        cols = _columns(slow[sel], lo[sel], int(w))
        per = flash_period.periodicity_batch(flash_series.flash_series_batch(cols, config, body_hz[sel], bin_m, n_bins))
        for name in fields:
            fields[name][sel] = getattr(per, name)
    return flash_period.PeriodicityBatch(**fields)


def _spectrogram(slow: np.ndarray, config: RadarConfig, win: int, hop: int,
                 fft_backend: str) -> tuple[np.ndarray, np.ndarray]:
    """`timefreq.spectrogram` (summed over the gate's columns) per row: (power (B, time, Doppler),
    frame times)."""
    x = slow
    if x.shape[1] < win:
        x = np.concatenate([x, np.zeros((x.shape[0], win - x.shape[1], x.shape[2]), x.dtype)], axis=1)
    frames = sliding_window_view(x, win, axis=1)[:, ::hop]  # (B, frames, bins, win)
    power = _fft_rows(frames, -1, rd.hann(win), "stft", fft_backend, _stft_power)
    t = (np.arange(power.shape[1]) * hop + win / 2) * config.pri_s
    return power, t


def _stft_power(z: np.ndarray) -> np.ndarray:
    """fftshift(|z|^2 summed over the gate's columns) of (B, frames, columns, win) transforms:
    `timefreq.spectrogram`'s floats (the squares on the interleaved view, the columns added in
    order as numpy's sum over that axis), without its temporaries."""
    p = flash_series.squared_magnitude(z)
    acc = p[:, :, 0].copy()
    for j in range(1, p.shape[2]):
        acc += p[:, :, j]
    return np.fft.fftshift(acc, axes=-1)


def _cadence(spec: tuple[np.ndarray, np.ndarray], fft_backend: str) -> tuple[np.ndarray, np.ndarray]:
    """`timefreq.cadence(...).spectrum()` per row: (cadence spectrum (B, cadence bins), cadence_hz)."""
    power, t = spec
    p = power - power.mean(axis=1, keepdims=True)
    mag = np.abs(_fft.rfft(p, axis=1, backend=fft_backend)).astype(p.dtype, copy=False)
    step = float(t[1] - t[0]) if t.size > 1 else 1.0
    return mag.sum(axis=2), np.fft.rfftfreq(p.shape[1], d=step)


def _cadence_features(cad: tuple[np.ndarray, np.ndarray], flash_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: the cadence spectrum's peak frequency above FLASH_RATE_MIN_HZ, and the share of its
    magnitude within one bin of a harmonic of the flash rate. The comb is laid at the flash rate as
    the feature vector reports it (float32): a rounding-level difference in the estimate (the same
    return at another scale) must not move a bin across the comb's edge."""
    spec, f = cad
    rows = spec.shape[0]
    use = f >= flash_series.FLASH_RATE_MIN_HZ
    if not use.any():
        return np.zeros(rows), np.zeros(rows)
    used = spec[:, use]
    total = np.maximum(used.sum(axis=1).astype(np.float64), _TINY)
    peak = np.where(total > _TINY, f[use][np.argmax(used, axis=1)], 0.0)
    if f.size < 2:
        return peak, np.zeros(rows)
    step = float(f[1] - f[0])
    fl = np.where(flash_hz > 0, np.asarray(flash_hz, np.float32).astype(np.float64), 1.0)[:, None]
    harm = np.abs(f / fl - np.round(f / fl)) * fl <= step
    on = np.where(use & harm, spec, np.float32(0.0)).sum(axis=1).astype(np.float64)
    return peak, np.where(flash_hz > 0, on / total, 0.0)


#: What `detections` calls a target: its CFAR cluster's peak this far above the profile's median
DETECTION_MIN_SNR_DB = 10.0


def detections(recording, clutter_suppression: bool = True,
               min_snr_db: float = DETECTION_MIN_SNR_DB) -> list[tuple[float, float]]:
    """The targets of the range profile: (range m, SNR dB over the profile's median) of the peak
    of each CFAR cluster (contiguous bins over threshold) at least `min_snr_db` strong, strongest
    first; a cluster within F.GATE_BINS of a stronger one is that one's (range sidelobes, blade
    flashes). [] for a CW return (no range) or an all-zero one. What `authn check --rid-capture`
    compares with the claims (non-cooperative targets); the features look at one target only."""
    if recording.domain == "cw":
        return []
    a = np.asarray(recording.iq)
    if a.ndim != 2 or a.shape[0] < 1 or a.shape[1] < 1:
        raise SignaturesError(f"IQ cube must be 2-D (n_chirps, n_samples), got shape {a.shape}")
    try:
        _, _, zero, profile = _range_spectra(a[None], clutter_suppression, recording.domain, [0],
                                             np.empty(a.shape, np.complex64)[None], "numpy")
    except RowError as exc:
        raise SignaturesError(exc.message) from None
    if zero[0]:
        return []
    looks = max(1, a.shape[0] - 1) if clutter_suppression else a.shape[0]
    hits, _ = rd.cfar(profile[0], looks)
    return _targets(profile[0], hits, recording.config, min_snr_db)


def _targets(profile: np.ndarray, hits: np.ndarray, config: RadarConfig,
             min_snr_db: float = DETECTION_MIN_SNR_DB) -> list[tuple[float, float]]:
    """`detections` of one row's range profile (float32, bins) and its CFAR hits."""
    noise = max(float(median(profile)), 1e-30)
    edges = np.flatnonzero(np.diff(hits, prepend=False, append=False))  # each cluster's [start, end)
    peaks: list[tuple[int, float]] = []
    for k, end in zip(edges[0::2].tolist(), edges[1::2].tolist()):
        peak = k + int(np.argmax(profile[k:end]))
        snr = 10.0 * math.log10(max(float(profile[peak]) / noise, 1e-30))
        if snr >= min_snr_db:
            peaks.append((peak, snr))
    kept: list[tuple[int, float]] = []
    for peak, snr in sorted(peaks, key=lambda p: -p[1]):
        if all(abs(peak - other) > F.GATE_BINS for other, _ in kept):
            kept.append((peak, snr))
    bin_m = config.range_bin_m(profile.shape[0])
    return [(config.range_offset_m + rd._interp_peak(profile, peak) * bin_m, snr) for peak, snr in kept]
