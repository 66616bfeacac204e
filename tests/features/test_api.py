"""The feature vector's contract: names and order, dtype, the RD patch, gating."""

from __future__ import annotations

import numpy as np
import pytest

from signatures.dsp import envelope
from signatures.dsp import feature_vector as F
from signatures.errors import SignaturesError
from signatures.features import FEATURE_NAMES, PATCH_SHAPE, extract, extract_iq

PAPER_11 = ("mean_range_m", "mean_doppler_mps", "std_range_m", "std_doppler_mps", "par_db",
            "spectral_centroid_hz", "spectral_bandwidth_hz", "peak_amplitude_db", "num_peaks",
            "energy_ratio", "entropy")


def test_names_and_order_are_fixed():
    assert FEATURE_NAMES[:11] == PAPER_11
    assert FEATURE_NAMES[11:] == (
        "range_m", "range_std_m", "radial_velocity_mps", "radial_velocity_std_mps", "flash_rate_hz",
        "flash_rate_std_hz", "rotor_rate_hz", "rotor_rate_std_hz", "rotor_count", "rotor_count_std",
        "tip_speed_mps", "tip_speed_std_mps", "blade_length_m", "blade_length_std_m", "tip_aliased",
        "flash_score", "flash_count", "flash_par_db", "doppler_occupancy", "cadence_peak_hz",
        "cadence_harmonic_ratio", "snr_db", "detected", *(f"flash_ac_{2 * k}ms" for k in range(1, 16)))


def test_envelope_features_name_their_lags():
    assert F.ENVELOPE_FEATURES == tuple(f"flash_ac_{round(lag * 1e3)}ms" for lag in envelope.LAGS_S)


def test_vector_patch_and_accessors(returns):
    res = extract(returns["m300_moving"])
    x = res.as_array()
    assert x.dtype == np.float32 and x.shape == (len(FEATURE_NAMES),)
    assert res.rd_patch.dtype == np.float32 and res.rd_patch.shape == PATCH_SHAPE
    assert 0.0 <= res.rd_patch.min() and res.rd_patch.max() == pytest.approx(1.0)
    assert res.range_m == res.features.range_m and res.detected
    assert x[FEATURE_NAMES.index("detected")] == 1.0


def test_expected_range_gates_the_detection(returns):
    rec = returns["m300_moving"]
    lo, hi = rec.config.range_window_m
    at = extract(rec, expected_range_m=400.0 + 6.0 * 600 * rec.config.pri_s / 2)
    assert at.detected and at.gate[0] <= 40 <= at.gate[1]
    away = extract(rec, expected_range_m=lo + 3.0)
    # the gate sits on the expected range (bin 3), wherever the noise peaks within +-2 bins of it
    assert not away.detected and away.gate[0] <= 3 < away.gate[1]
    with pytest.raises(SignaturesError, match="outside the recorded window"):
        extract(rec, expected_range_m=hi + 10.0)


def test_bad_cubes_are_specific_errors():
    from signatures.radar import get_preset

    cfg = get_preset("paper").config
    for bad, msg in ((np.zeros(10, np.complex64), "2-D"), (np.zeros((0, 8), np.complex64), "2-D"),
                     (np.full((4, 4), np.nan, np.complex64), "NaN"), (np.zeros((4, 4), bool), "numeric")):
        with pytest.raises(SignaturesError, match=msg):
            extract_iq(bad, cfg)
    with pytest.raises(SignaturesError, match="gate_bins"):
        extract_iq(np.ones((8, 8), np.complex64), cfg, gate_bins=0)


def test_quick_tier_computes_its_subset_exactly(returns):
    from signatures.features import QUICK_FEATURES

    idx = [FEATURE_NAMES.index(n) for n in QUICK_FEATURES]
    rest = [i for i in range(len(FEATURE_NAMES)) if i not in idx]
    for rec in returns.values():
        full, quick = extract(rec).as_array(), extract(rec, quick=True)
        np.testing.assert_array_equal(quick.as_array()[idx], full[idx])
        assert not quick.as_array()[rest].any() and not quick.rd_patch.any()


def test_cnn_patch_is_built_on_first_use(returns):
    res = extract(returns["m300_moving"])
    assert "rd_patch" not in res.__dict__  # not computed by extract
    patch = res.rd_patch
    assert res.rd_patch is patch  # computed once
