"""Numerical soundness: scale invariance, finiteness on degenerate cubes, float32 vs float64,
shift properties. Any RuntimeWarning fails a test here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from signatures.dsp import flash_series, rd
from signatures.features import FEATURE_NAMES, extract_iq
from signatures.radar import get_preset

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
       log10_factor=st.floats(-20, 20))
def test_float32_transforms_agree_with_float64_transforms(returns, which, log10_factor):
    """Features from complex64 transforms (the 'scipy' backend) against complex128 ones (the
    'numpy' backend), on the same scaled cube: continuous features within RTOL."""
    rec = returns[which]
    iq = rec.iq.astype(np.complex128) * 10.0 ** log10_factor
    single = extract_iq(iq, rec.config, fft_backend="scipy")
    double = extract_iq(iq, rec.config, fft_backend="numpy")
    _close(double.as_array(), single.as_array(), skip=(PA,))
    assert abs(double.features.peak_amplitude_db - single.features.peak_amplitude_db) < 1e-3


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


def test_doppler_shift_moves_only_the_body(returns, monkeypatch):
    """Shifting the whole return in Doppler (no clutter suppression) moves the velocity by
    the shift and leaves the body-relative micro-Doppler features unchanged. The flash series'
    clutter pass is anchored at zero Doppler in the radar's frame, where clutter is, and a shift
    moves the return against it: off here, so the body-relative part is what is tested."""
    monkeypatch.setattr(flash_series, "CLUTTER_PASS_SHARE", math.inf)
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
