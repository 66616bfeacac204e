"""The batched feature front end (`signatures.dsp.extraction`) gives the single-return path's
results row by row, on either FFT backend (the single path run with the same `fft_backend`):
the cube stage's outputs to float32 rounding; same detection, gate and counts, every feature within
REL of max(|value|, 1) (the slow-time stage sums in another order), the same CNN patch."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lab.bench.stress import cases
from signatures.dsp import extraction as bf
from signatures.dsp import feature_vector as FV
from signatures import features as F
from signatures.dsp import rd
from signatures.train.dataset import DatasetSpec, draw_scene
from signatures.sim.domain import as_recorded
from signatures.errors import SignaturesError
from signatures.profiles import shipped_profiles
from signatures.sim.simulate import simulate

REL = 1e-5
BACKENDS = ("numpy", "scipy")
#: features that are counts or flags: equal, not close
EXACT = ("num_peaks", "flash_count", "rotor_count", "tip_aliased", "detected")


def _drawn(preset: str, n: int):
    """n dataset scenes of `preset` (SNR -5..30 dB; UAVs hovering and moving, birds, empty
    scenes) and their simulated recordings."""
    spec = DatasetSpec(preset, tuple(shipped_profiles().values()), "test", n)
    out = []
    for i in range(n):
        scene, seed = draw_scene(spec, i)
        out.append((scene, simulate(scene, spec.waveform, seed=seed)[0]))
    return out


def drawn_fixture(preset: str, n: int):
    """A module-scoped fixture, named after the preset, of `_drawn(preset, n)`."""
    return pytest.fixture(scope="module", name=preset)(lambda: _drawn(preset, n))


paper = drawn_fixture("paper", 30)
wide = drawn_fixture("wide", 8)


def assert_same(single: F.FeatureResult, batch: F.FeatureResult, where: str, patch_atol: float = 1e-5) -> None:
    """Same detection, gate and counts; every feature and physics estimate within REL of
    max(|value|, 1); the CNN patch within `patch_atol`."""
    assert (batch.detected, batch.gate) == (single.detected, single.gate), where
    a, b = single.as_array().astype(np.float64), batch.as_array().astype(np.float64)
    exact = [F.FEATURE_NAMES.index(n) for n in EXACT]
    assert np.array_equal(a[exact], b[exact]), f"{where}: counts {a[exact]} != {b[exact]}"
    err = np.abs(a - b) / np.maximum(np.abs(a), 1.0)
    bad = {n: (a[i], b[i]) for i, n in enumerate(F.FEATURE_NAMES) if not err[i] <= REL}
    assert not bad, f"{where}: {bad}"
    assert batch.physics.keys() == single.physics.keys(), where
    for name, value in single.physics.items():
        assert abs(batch.physics[name] - value) <= REL * max(abs(value), 1.0), (where, name)
    np.testing.assert_allclose(batch.rd_patch, single.rd_patch, rtol=0, atol=patch_atol, err_msg=where)


def _expected(config, n: int, detected: list[float]) -> list[float | None]:
    """None, the single path's own detected range, or a range elsewhere in the window, in turn."""
    lo, hi = config.range_window_m
    out: list[float | None] = []
    for i in range(n):
        r = detected[i] if i % 3 == 1 else lo + (hi - lo) * ((0.37 * i) % 1.0)
        out.append(None if i % 3 == 0 or not lo <= r < hi else r)
    return out


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("preset", ["paper", "wide"])
@pytest.mark.parametrize("gated", [False, True], ids=["no-expected-range", "expected-ranges"])
def test_batch_equals_single_on_simulated_returns(request, preset, gated, backend):
    drawn = request.getfixturevalue(preset)
    scenes = [s for s, _ in drawn]
    if preset == "paper":  # the draw covers what the features must handle
        assert {s.kind for s in scenes} == {"uav", "bird", "none"}
        assert any(s.hovering for s in scenes if s.kind == "uav")
        assert any(not s.hovering for s in scenes if s.kind == "uav")
    # one radar: every cube under the first one's configuration (only the range offset differs)
    config = drawn[0][1].config
    iq = np.stack([r.iq for _, r in drawn])
    expected = None
    if gated:
        expected = _expected(config, len(drawn), [F.extract_iq(c, config).range_m for c in iq])
    results = bf.extract_batch(iq, config, expected, fft_backend=backend)
    assert len(results) == len(drawn)
    for b, res in enumerate(results):
        single = F.extract_iq(iq[b], config, None if expected is None else expected[b], fft_backend=backend)
        assert_same(single, res, f"{preset} row {b} ({scenes[b].label}, {scenes[b].snr_db:.0f} dB)")


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("options", [dict(), dict(suppress=False), dict(domain="range")], ids=str)
def test_cube_stage_is_the_single_paths(paper, backend, options):
    """Spectra of the gate and patch columns, range profile and mu of every row equal the single
    path's own arrays on the same backend to `CUBE_ULPS` float32 ulps of the row's largest value
    (the same transforms; the scale riding on the window is exact, but an FFT library may group
    a block's transforms into vector lanes whose rounding differs by a machine's instructions)."""
    suppress, domain = options.get("suppress", True), options.get("domain", "if")
    recs = [r if domain == "if" else as_recorded(r, domain) for _, r in paper[:8]]
    on_window = np.stack([r.iq for r in recs])
    on_window[3] *= np.float32(2.0 ** -19)  # the scale rides on the window ...
    first = on_window.copy()
    first[5] *= np.float32(2.0 ** 40)  # ... or, with a row far from unit scale, is applied first
    for iq in (on_window, first):
        _assert_cube_is_single(bf._cube_stage(iq, [None] * len(iq), F.GATE_BINS, suppress, domain,
                                              list(range(len(iq))), backend), iq, suppress, domain, backend)


def _range_spectrum(iq: np.ndarray, suppress: bool, domain: str, backend: str) -> np.ndarray:
    """The plain per-return range spectrum: the range FFT of IF; a range or CW cube less its mean."""
    if domain == "if":
        return rd.range_fft(iq, suppress, backend)
    return iq - iq.mean(axis=0, keepdims=True) if suppress else iq


def _assert_cube_is_single(cube, iq: np.ndarray, suppress: bool, domain: str, backend: str) -> None:
    for b in range(len(iq)):
        prep = rd.prepare(iq[b])
        spectrum = _range_spectrum(prep.iq, suppress, domain, backend)
        mu = _range_spectrum(prep.iq.mean(axis=0, keepdims=True), False, domain, backend)[0]
        g, p = cube.gate_lo[b], cube.patch_lo[b]
        assert cube.log2_scale[b] == prep.log2_scale and not cube.zero[b]
        assert _close(cube.profile[b], rd.range_profile(spectrum)), f"row {b} profile"
        assert _close(cube.mu[b], mu), f"row {b} mu"
        assert _close(cube.slow[b], spectrum[:, g:g + F.GATE_BINS], spectrum), f"row {b} gate"
        assert _close(cube.patch_cols[b], spectrum[:, p:p + F.PATCH_SHAPE[1]], spectrum), f"row {b} patch"


#: float32 ulps (of the row's largest magnitude) the cube stage may differ from the single path by
CUBE_ULPS = 8


def _close(got: np.ndarray, want: np.ndarray, scale: np.ndarray | None = None) -> bool:
    """|got - want| within `CUBE_ULPS` float32 ulps of the largest magnitude of `scale` (default
    `want`): what rounding in another grouping of the same transforms can move."""
    ref = float(np.abs(want if scale is None else scale).max())
    err = float(np.abs(got.astype(np.complex128) - want).max(initial=0.0))
    return err <= CUBE_ULPS * float(np.finfo(np.float32).eps) * ref


def test_backends_differ_only_by_float32_rounding(paper):
    """scipy's single-precision transforms move no count, gate or detection against numpy's
    complex128 ones on these returns, and the spectra by float32 rounding only."""
    config = paper[0][1].config
    iq = np.stack([r.iq for _, r in paper[:8]])
    ours = bf.extract_batch(iq, config, fft_backend="scipy")
    for b, res in enumerate(bf.extract_batch(iq, config, fft_backend="numpy")):
        assert (res.detected, res.gate) == (ours[b].detected, ours[b].gate)
    prep = rd.prepare(iq[0])
    s32, s64 = (_range_spectrum(prep.iq, True, "if", be) for be in ("scipy", "numpy"))
    assert not np.array_equal(s32, s64)  # really two backends
    assert np.abs(s32 - s64).max() <= 1e-5 * np.abs(s64).max()


@pytest.mark.parametrize("options", [dict(clutter_suppression=False), dict(gate_bins=1), dict(gate_bins=9),
                                     dict(domain="range"), dict(domain="cw")], ids=str)
def test_batch_equals_single_with_options(paper, options):
    config = paper[0][1].config
    iq = np.stack([r.iq for _, r in paper[:8]])
    domain = options.get("domain", "if")
    if domain != "if":
        iq = np.stack([as_recorded(r, domain).iq for _, r in paper[:8]])
    results = bf.extract_batch(iq, config, **options)  # the default backend: scipy
    single_opts = {k: v for k, v in options.items() if k != "domain"}
    for b, res in enumerate(results):
        assert_same(F.extract_iq(iq[b], config, domain=domain, fft_backend=bf.DEFAULT_FFT_BACKEND, **single_opts),
                    res, f"{options} row {b}")


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_stress_cases_batched_as_single(preset):
    """Every numerical stress case that gives features (scales 1e-30..1e30, ADC dtypes,
    degenerate and odd-shaped cubes, extreme SNR and geometry), batched by `extract_many`
    with the cases that share its configuration, shape and dtype."""
    recs, singles = [], []
    for group, name, make in cases(preset, quick=True):
        rec = make()
        try:
            singles.append((f"{group}/{name}", F.extract(rec, fft_backend=bf.DEFAULT_FFT_BACKEND)))
        except SignaturesError:
            continue
        recs.append(rec)
    assert len(recs) >= 20
    batched = bf.extract_many(recs)
    for (name, single), res in zip(singles, batched):
        assert_same(single, res, f"{preset} {name}")


def test_extract_many_keeps_order_over_a_mixed_list(paper, wide):
    base = [r for _, r in paper[:4]]
    recs = [base[0], wide[0][1], as_recorded(base[1], "range"), base[2], as_recorded(base[3], "cw"),
            wide[1][1], base[0]]
    lo, hi = base[2].config.range_window_m
    far = base[0].config.range_window_m[0] + 20.0  # away from the (centred) target
    expected = [None, None, None, 0.5 * (lo + hi), None, None, far]
    results = bf.extract_many(recs, expected, memory_bytes=1)  # batches of one row
    assert len(results) == len(recs)
    for i, (rec, res) in enumerate(zip(recs, results)):
        assert_same(F.extract(rec, expected[i], fft_backend="scipy"), res, f"item {i} ({rec.domain})")
    assert results[0].as_array().tolist() != results[6].as_array().tolist()  # gated away from the target
    by_default = bf.extract_many(recs, expected)
    for i, res in enumerate(by_default):
        assert_same(results[i], res, f"item {i}, default batch size")


def test_extract_many_batches_recordings_whose_range_offsets_differ(paper, monkeypatch):
    """Simulated recordings centre their window on the target: one batch all the same, and
    each row keeps its own absolute ranges and window (for the expected range)."""
    recs = [r for _, r in paper]
    assert len({r.config.range_offset_m for r in recs}) > 1
    expected = [s.range_m if i % 2 else None for i, (s, _) in enumerate(paper)]
    calls = []
    inner = bf._extract
    monkeypatch.setattr(bf, "_extract", lambda iq, *a, **k: calls.append(len(iq)) or inner(iq, *a, **k))
    results = bf.extract_many(recs, expected)
    assert calls == [len(recs)]
    for i, (rec, res) in enumerate(zip(recs, results)):
        assert_same(F.extract(rec, expected[i], fft_backend="scipy"), res, f"recording {i}")


def test_bad_rows_raise_the_single_path_error_naming_the_row(paper):
    config = paper[0][1].config
    iq = np.stack([r.iq for _, r in paper[:3]])
    bad = iq.copy()
    bad[2, 5, 7] = np.nan
    with pytest.raises(SignaturesError) as single:
        F.extract_iq(bad[2], config)
    with pytest.raises(SignaturesError) as batch:
        bf.extract_batch(bad, config)
    assert str(batch.value) == f"row 2: {single.value}"
    far = config.range_window_m[1] + 10.0
    with pytest.raises(SignaturesError) as single:
        F.extract_iq(iq[1], config, far)
    with pytest.raises(SignaturesError) as batch:
        bf.extract_batch(iq, config, [None, far, None])
    assert str(batch.value) == f"row 1: {single.value}"
    with pytest.raises(SignaturesError, match="row 1: expected range"):
        bf.extract_many([paper[0][1], paper[1][1]], [None, far])
    with pytest.raises(SignaturesError, match="3-D"):
        bf.extract_batch(iq[0], config)
    with pytest.raises(SignaturesError, match="2 expected ranges for 3 returns"):
        bf.extract_batch(iq, config, [None, None])
    with pytest.raises(SignaturesError, match="gate_bins"):
        bf.extract_batch(iq, config, gate_bins=0)
    assert bf.extract_batch(iq[:0], config) == []
    for call in (lambda: bf.extract_batch(iq, config, fft_backend="fftw"),
                 lambda: bf.extract_many([paper[0][1]], fft_backend="fftw"),
                 lambda: F.extract_iq(iq[0], config, fft_backend="fftw")):
        with pytest.raises(SignaturesError, match="unknown FFT backend 'fftw'"):
            call()


def test_batch_size_follows_memory(paper):
    n, k = paper[0][1].iq.shape
    assert 1 <= bf.batch_size(8192, 64) <= bf.batch_size(n, k) <= bf.MAX_BATCH
    assert bf.batch_size(n, k, memory_bytes=1) == 1
    assert bf.batch_size(n, k, memory_bytes=1 << 50) == bf.MAX_BATCH
    half, full = bf.batch_size(n, k, memory_bytes=64 << 20), bf.batch_size(n, k, memory_bytes=128 << 20)
    assert 1 < half < bf.MAX_BATCH and 2 * half <= full <= 2 * half + 1
    # the estimate covers what a row really costs: input cube plus the batch's peak per row
    config = paper[0][1].config
    peaks = {}
    for rows in (4, 12):
        iq = np.stack([paper[i % len(paper)][1].iq for i in range(rows)])
        bf.extract_batch(iq, config)  # workspaces, caches
        tracemalloc.start()
        bf.extract_batch(iq, config)
        peaks[rows] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    per_row = (peaks[12] - peaks[4]) / 8 + paper[0][1].iq.astype(np.complex64).nbytes
    assert bf.batch_size(n, k, memory_bytes=int(10 * per_row)) <= 10


@pytest.fixture(scope="module")
def four(paper):
    config = paper[0][1].config
    iq = np.stack([paper[i][1].iq for i in (0, 5, 10, 11)])
    return config, iq, bf.extract_batch(iq, config)


@settings(max_examples=10, deadline=None)
@given(row=st.integers(0, 3), exponent=st.integers(-20, 20).filter(bool))
def test_scaling_one_row_by_a_power_of_ten(four, row, exponent):
    """Only that row's peak amplitude moves (by 20 dB per decade); the other rows are untouched."""
    config, iq, base = four
    scaled = iq.copy()
    scaled[row] = (iq[row].astype(np.complex128) * 10.0 ** exponent).astype(np.complex64)
    results = bf.extract_batch(scaled, config)
    peak = F.FEATURE_NAMES.index("peak_amplitude_db")
    for b, res in enumerate(results):
        if b != row:
            assert res.gate == base[b].gate and np.array_equal(res.as_array(), base[b].as_array())
            continue
        a, s = base[b].as_array().astype(np.float64), res.as_array().astype(np.float64)
        assert s[peak] == pytest.approx(a[peak] + 20.0 * exponent, abs=1e-3)
        err = np.abs(a - s) / np.maximum(np.abs(a), 1.0)
        err[peak] = 0.0
        assert err.max() <= REL, {F.FEATURE_NAMES[i]: (a[i], s[i]) for i in np.flatnonzero(err > REL)}
        assert res.gate == base[b].gate and res.detected == base[b].detected


@settings(max_examples=300, deadline=None)
@given(profiles=st.lists(st.lists(st.sampled_from([0.0, 1.0, 2.0, 8.0, 30.0, 100.0, 1e3]),
                                  min_size=3, max_size=300), min_size=1, max_size=4),
       noise=st.sampled_from([1e-3, 0.05, 1.0]))
def test_peak_count_equals_the_single_path_with_ties_and_plateaus(profiles, noise):
    """Prominence by range tables counts the same peaks as a plain per-profile count (equal
    levels, plateaus and profiles long enough to be pooled included)."""
    size = min(len(p) for p in profiles)
    d = np.array([p[:size] for p in profiles], dtype=np.float32)
    counts = bf._count_peaks(d, np.full(len(d), noise))
    assert counts.tolist() == [_count_peaks_reference(row, noise) for row in d]


def _count_peaks_reference(d: np.ndarray, noise: float) -> int:
    """The plain per-profile peak count (candidate x band matrices): local maxima of the profile
    pooled to <= FV.PEAK_PROFILE_BANDS bands, >= FV.PEAK_PROMINENCE_DB above the higher of the
    lowest points between them and the next higher peak (or the ends) on each side, and
    >= FV.PEAK_ABOVE_NOISE_DB above the noise per band."""
    group = max(1, d.size // FV.PEAK_PROFILE_BANDS)
    m = (d.size // group) * group
    pooled = d[:m].reshape(-1, group).sum(axis=1)
    with np.errstate(divide="ignore"):
        y = np.log(np.maximum(pooled, np.float32(FV.TINY))) * FV.DB_PER_LN
    floor = 10.0 * math.log10(max(noise * group, 1e-30)) + FV.PEAK_ABOVE_NOISE_DB
    n = y.size
    rise = np.ones(n, dtype=bool)
    rise[1:] = y[1:] > y[:-1]
    fall = np.ones(n, dtype=bool)
    fall[:-1] = y[:-1] >= y[1:]
    cand = np.flatnonzero((y >= floor) & rise & fall)
    if cand.size == 0:
        return 0
    # prominence, vectorised over candidates (n <= FV.PEAK_PROFILE_BANDS): the base on each side is
    # the lowest point between the candidate and the nearest higher point (or the end)
    idx = np.arange(n)
    yc = y[cand][:, None]
    higher = y[None, :] > yc
    left, right = idx[None, :] < cand[:, None], idx[None, :] > cand[:, None]
    last_left = np.where(higher & left, idx[None, :], -1).max(axis=1)
    first_right = np.where(higher & right, idx[None, :], n).min(axis=1)
    span_l = left & (idx[None, :] > last_left[:, None])
    span_r = right & (idx[None, :] < first_right[:, None])
    base_l = np.where(span_l, y[None, :], np.inf).min(axis=1)
    base_r = np.where(span_r, y[None, :], np.inf).min(axis=1)
    base_l = np.where(span_l.any(axis=1), base_l, y[cand])
    base_r = np.where(span_r.any(axis=1), base_r, y[cand])
    return int(np.count_nonzero(y[cand] - np.maximum(base_l, base_r) >= FV.PEAK_PROMINENCE_DB))


def test_torch_stays_optional(paper, monkeypatch):
    """Without torch, device='auto' is the numpy path and a named device says what is missing;
    the default path never imports torch."""
    import subprocess
    import sys

    import signatures.dsp

    config = paper[0][1].config
    iq = np.stack([r.iq for _, r in paper[:4]])
    monkeypatch.setitem(sys.modules, "signatures.dsp.torch_cube", None)  # its import now fails
    monkeypatch.delattr(signatures.dsp, "torch_cube", raising=False)
    auto = bf.extract_batch(iq, config, device="auto")
    for b, res in enumerate(bf.extract_batch(iq, config)):
        assert np.array_equal(res.as_array(), auto[b].as_array())
    with pytest.raises(SignaturesError, match="device 'cpu' needs torch"):
        bf.extract_batch(iq, config, device="cpu")
    code = ("import sys, numpy as np; from signatures.dsp import extraction as bf; "
            "from signatures.radar import get_preset; "
            "bf.extract_batch(np.ones((4, 64, 16), np.complex64), get_preset('paper').config); "
            "assert 'torch' not in sys.modules, 'torch imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


def _ulps_apart(iq: np.ndarray, seed: int, ulps: int = 4) -> np.ndarray:
    """`iq` with each component moved by up to `ulps` float32 ulps (random per element)."""
    rng = np.random.default_rng(seed)
    parts = [iq.real.astype(np.float32), iq.imag.astype(np.float32)]
    for p in parts:
        for _ in range(ulps):
            step = rng.integers(-1, 2, p.shape)
            p[:] = np.where(step > 0, np.nextafter(p, np.float32(np.inf)),
                            np.where(step < 0, np.nextafter(p, np.float32(-np.inf)), p))
    return (parts[0] + 1j * parts[1]).astype(np.complex64)


def test_a_constant_cube_gives_the_same_counts_however_it_is_batched_or_rounded(paper):
    """A cube of one repeated chirp carries no slow-time signal (its clutter-suppressed spectra
    hold only rounding, whose pattern varies with the batch's memory layout): alone, batched
    among real returns at any position, moved by a few ulps, or on one BLAS thread, it gives the
    all-zero cube's result."""
    from signatures.dsp.threads import one_blas_thread

    rec = paper[0][1]
    const = np.full_like(rec.iq, 3 - 2j)
    config = rec.config
    empty = FV.empty(config, *const.shape, None).as_array()
    others = [r.iq for _, r in paper[1:6]]
    cubes = [const] + [_ulps_apart(const, seed) for seed in range(3)]
    for cube in cubes:
        assert np.array_equal(bf.extract_iq(cube, config).as_array(), empty)
        for at in (0, 2, 5):
            batch = np.stack(others[:at] + [cube] + others[at:])
            assert np.array_equal(bf.extract_batch(batch, config)[at].as_array(), empty), at
    with one_blas_thread():
        batch = np.stack(others + cubes)
        for res in bf.extract_batch(batch, config)[len(others):]:
            assert np.array_equal(res.as_array(), empty)
    moving = const.copy()
    moving[1::2] *= np.float32(1.001)  # chirps that differ beyond rounding: a signal, not empty
    assert not np.array_equal(bf.extract_iq(moving, config).as_array(), empty)
