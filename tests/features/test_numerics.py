"""Numerical soundness: scale invariance, finiteness on degenerate cubes, float32 vs float64,
shift properties. Any RuntimeWarning fails a test here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from signatures import rd
from signatures.features import FEATURE_NAMES, extract_iq
from signatures.radar import get_preset
from tests.features.conftest import sim

pytestmark = pytest.mark.filterwarnings("error")
CFG = get_preset("paper").config
PA = FEATURE_NAMES.index("peak_amplitude_db")
SETTINGS = settings(max_examples=25, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])
#: Continuous features agree to this relative tolerance (float32 round-off through FFTs, sums).
RTOL = 2e-3


def _close(a: np.ndarray, b: np.ndarray, skip: tuple[int, ...] = ()) -> None:
    keep = [i for i in range(a.size) if i not in skip]
    scale = np.maximum(np.abs(a[keep]), 1.0)
    bad = np.abs(a[keep] - b[keep]) > RTOL * scale
    names = [FEATURE_NAMES[keep[i]] for i in np.flatnonzero(bad)]
    assert not names, f"features differ: {names}"


@SETTINGS
@given(which=st.sampled_from(["m300_moving", "m600_hover", "bird", "none"]),
       log10_factor=st.floats(-20.0, 20.0))
def test_scale_invariance(returns, which, log10_factor):
    rec = returns[which]
    factor = 10.0 ** log10_factor
    ref = extract_iq(rec.iq, rec.config).as_array()
    got = extract_iq(rec.iq.astype(np.complex128) * factor, rec.config).as_array()
    _close(ref, got, skip=(PA,))
    assert got[PA] - ref[PA] == pytest.approx(20.0 * log10_factor, abs=1e-2)


def _cube(kind: str, n: int, m: int, scale: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if kind == "noise":
        return (rng.standard_normal((n, m)) + 1j * rng.standard_normal((n, m))) * scale
    if kind == "zero":
        return np.zeros((n, m), np.complex128)
    if kind == "constant":
        return np.full((n, m), scale * (1 + 1j))
    cube = np.zeros((n, m), np.complex128)  # one huge spike
    cube[rng.integers(n), rng.integers(m)] = scale
    return cube


@SETTINGS
@given(kind=st.sampled_from(["noise", "zero", "constant", "spike"]), n=st.integers(1, 96),
       m=st.integers(1, 40), log10_scale=st.floats(-30, 30), seed=st.integers(0, 2**16),
       dtype=st.sampled_from([np.complex64, np.complex128, np.float16, np.float32, np.int16]),
       suppress=st.booleans())
def test_finite_on_any_cube(kind, n, m, log10_scale, seed, dtype, suppress):
    cube = _cube(kind, n, m, 10.0 ** log10_scale, seed)
    if dtype in (np.float16, np.int16, np.float32):
        info = np.finfo(dtype) if dtype != np.int16 else np.iinfo(dtype)
        cube = np.clip(cube.real, -float(info.max), float(info.max))
    res = extract_iq(cube.astype(dtype), CFG, clutter_suppression=suppress)
    x = res.as_array()
    assert np.all(np.isfinite(x)), dict(zip(FEATURE_NAMES, x))
    assert np.all(np.isfinite(res.rd_patch))


@pytest.mark.parametrize("snr_db", [-40, -20, 0, 20, 40, 60, 80])
@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_finite_over_snr(snr_db, preset):
    rec, _ = sim(preset=preset, snr_db=snr_db, radial_speed_mps=3.0)
    x = extract_iq(rec.iq, rec.config).as_array()
    assert np.all(np.isfinite(x))


def test_degenerate_named_cases():
    for cube in (np.zeros((600, 80), np.complex64), np.ones((600, 80), np.complex64),
                 np.ones((1, 80), np.complex64), np.full((600, 80), 1e30 + 0j, np.complex128)):
        for suppress in (True, False):
            res = extract_iq(cube, CFG, clutter_suppression=suppress)
            assert np.all(np.isfinite(res.as_array()))
    zero = extract_iq(np.zeros((600, 80), np.complex64), CFG)
    assert not zero.detected and zero.features.peak_amplitude_db == -999.0


@SETTINGS
@given(seed=st.integers(0, 2**16), rel=st.floats(1e-9, 1e-7))
def test_float32_and_float64_inputs_agree(returns, seed, rel):
    """A complex128 cube and its complex64 rounding give the same features within RTOL."""
    rec = returns["m300_moving"]
    rng = np.random.default_rng(seed)
    wide = rec.iq.astype(np.complex128) * (1.0 + rel * rng.standard_normal(rec.iq.shape))
    _close(extract_iq(wide.astype(np.complex64), rec.config).as_array(),
           extract_iq(wide, rec.config).as_array())


@SETTINGS
@given(which=st.sampled_from(["m300_moving", "m600_hover", "bird", "none"]),
       log10_factor=st.floats(-20, 20))
def test_float32_pipeline_agrees_with_float64_pipeline(returns, which, log10_factor):
    """The default float32 pipeline against every stage in float64 (`float64=True`), on the
    same scaled cube: continuous features within RTOL, and the float64 path really is wider
    (its arrays differ from float32 round-off somewhere)."""
    rec = returns[which]
    iq = rec.iq.astype(np.complex128) * 10.0 ** log10_factor
    single = extract_iq(iq, rec.config)
    double = extract_iq(iq, rec.config, float64=True)
    _close(double.as_array(), single.as_array(), skip=(PA,))
    assert abs(double.features.peak_amplitude_db - single.features.peak_amplitude_db) < 1e-3
    assert rd.prepare(iq, float64=True).iq.dtype == np.complex128
    assert rd.range_profile(rd.range_fft(rd.prepare(iq, float64=True).iq)).dtype == np.float64


@SETTINGS
@given(seed=st.integers(0, 2**16))
def test_range_profile_ignores_chirp_order(returns, seed):
    """The range profile and CFAR detection depend on the set of chirps, not their order."""
    rec = returns["m300_moving"]
    perm = np.random.default_rng(seed).permutation(rec.n_chirps)
    a = rd.range_profile(rd.range_fft(rd.prepare(rec.iq).iq))
    b = rd.range_profile(rd.range_fft(rd.prepare(rec.iq[perm]).iq))
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6 * float(a.max()))
    da, db = rd.detect(a, rec.n_chirps - 1), rd.detect(b, rec.n_chirps - 1)
    assert (da.detected, da.peak_bin, da.n_hits) == (db.detected, db.peak_bin, db.n_hits)
    assert da.snr_db == pytest.approx(db.snr_db, abs=1e-3)


@SETTINGS
@given(shift=st.integers(-30, 30), axis=st.sampled_from([0, 1]))
def test_modulation_rolls_the_spectrum(returns, shift, axis):
    """exp(j 2 pi m k / N) along one axis rolls that axis' spectrum by m bins exactly
    (periodic Hann windows commute with the modulation)."""
    rec = returns["bird"]
    iq = rd.prepare(rec.iq).iq.astype(np.complex128)
    n = iq.shape[axis]
    ramp = np.exp(2j * math.pi * shift * np.arange(n) / n)
    mod = iq * (ramp[:, None] if axis == 0 else ramp[None, :])
    if axis == 1:
        a = rd.range_profile(rd.range_fft(iq.astype(np.complex64), False))
        b = rd.range_profile(rd.range_fft(mod.astype(np.complex64), False))
    else:
        a = np.abs(rd.doppler_spectrum(iq[:, 40:41].astype(np.complex64))[:, 0]) ** 2
        b = np.abs(rd.doppler_spectrum(mod[:, 40:41].astype(np.complex64))[:, 0]) ** 2
    np.testing.assert_allclose(np.roll(a, shift), b, rtol=1e-3, atol=1e-5 * float(a.max()))


def test_doppler_shift_moves_only_the_body(returns):
    """Shifting the whole return in Doppler (no clutter suppression) moves the velocity by
    the shift and leaves the body-relative micro-Doppler features unchanged."""
    rec = returns["m300_moving"]
    n = rec.n_chirps
    m = 40
    ramp = np.exp(2j * math.pi * m * np.arange(n) / n)[:, None]
    a = extract_iq(rec.iq, rec.config, clutter_suppression=False).features
    b = extract_iq(rec.iq * ramp, rec.config, clutter_suppression=False).features
    # one Doppler bin in m/s at the sweep's mid frequency (RadarConfig.doppler_wavelength_m)
    bin_mps = rec.config.prf_hz / n * rec.config.doppler_wavelength_m(rec.n_samples) / 2
    assert b.radial_velocity_mps - a.radial_velocity_mps == pytest.approx(m * bin_mps, abs=1e-3)
    for name in ("spectral_centroid_hz", "spectral_bandwidth_hz", "par_db", "energy_ratio", "entropy",
                 "std_doppler_mps", "num_peaks", "flash_rate_hz"):
        assert getattr(b, name) == pytest.approx(getattr(a, name), rel=RTOL, abs=1e-3), name
