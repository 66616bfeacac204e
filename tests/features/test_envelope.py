"""The flash envelope's autocorrelation (`signatures.dsp.envelope`): it finds a flash train's period
at any PRF, is independent of the return's scale, and stays finite and bounded on any input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from signatures.dsp import envelope
from signatures.radar import RadarConfig, get_preset


def _cw(prf_hz: float, carrier_hz: float = 3.3e9) -> RadarConfig:
    pri = 1.0 / prf_hz
    return RadarConfig(carrier_hz=carrier_hz, bandwidth_hz=prf_hz, ramp_s=pri, pri_s=pri, sample_rate_hz=prf_hz)


def _flash_train(config: RadarConfig, n: int, period_s: float, seed: int = 0, cols: int = 3) -> np.ndarray:
    """(1, n, cols) slow time: weak noise, and every `period_s` a 0.3 ms broadband burst (a blade flash)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * config.pri_s
    x = 0.01 * (rng.standard_normal((n, cols)) + 1j * rng.standard_normal((n, cols)))
    on = np.mod(t - 0.3 * period_s, period_s) < 0.3e-3
    x[on] += rng.standard_normal((int(on.sum()), cols)) + 1j * rng.standard_normal((int(on.sum()), cols))
    return x[None].astype(np.complex64)


def _lag(lag_s: float) -> int:
    return envelope.LAGS_S.index(min(envelope.LAGS_S, key=lambda v: abs(v - lag_s)))


def test_a_flash_train_correlates_at_its_period_at_any_prf():
    """A 10 ms flash train peaks at the 10 ms lag and dips half a period away, whether sampled by
    the paper's 77 GHz FMCW chirps or by a 5 kHz S-band CW radar; the two agree."""
    rows = []
    for config, n in ((get_preset("paper").config, 2400), (_cw(5000.0), 1000)):
        ac = envelope.autocorrelation(_flash_train(config, n, 0.010), config, np.zeros(1))[0]
        assert ac[_lag(0.010)] > 0.5 and ac[_lag(0.020)] > 0.3
        assert ac[_lag(0.004)] < 0.0 and ac[_lag(0.006)] < 0.0
        rows.append(ac)
    assert np.max(np.abs(rows[0][:10] - rows[1][:10])) < 0.3


def test_lags_beyond_the_dwell_read_zero_and_short_dwells_give_zeros():
    config = get_preset("paper").config
    ac = envelope.autocorrelation(_flash_train(config, 600, 0.008), config, np.zeros(1))[0]
    reach = (600 - envelope.frames(config, 600)[0]) * config.pri_s  # frame centres' span
    assert np.all(ac[np.array(envelope.LAGS_S) > reach] == 0.0) and np.any(ac != 0.0)
    assert not envelope.autocorrelation(_flash_train(config, 40, 0.008), config, np.zeros(1)).any()
    assert envelope.autocorrelation(np.zeros((0, 600, 3), np.complex64), config, np.zeros(0)).shape == (0, 15)


def test_the_body_line_is_left_out():
    """A strong moving body line added to the flash train leaves the envelope (and so the
    autocorrelation) almost as it was, when the body's Doppler is named."""
    config = get_preset("paper").config
    x = _flash_train(config, 2400, 0.010)
    body_hz = 2 * 5.0 / config.wavelength_m
    line = 30.0 * np.exp(2j * np.pi * body_hz * np.arange(2400) * config.pri_s)[None, :, None]
    plain = envelope.autocorrelation(x, config, np.zeros(1))[0]
    with_body = envelope.autocorrelation((x + line).astype(np.complex64), config, np.array([body_hz]))[0]
    assert np.max(np.abs(plain - with_body)) < 0.1


@settings(max_examples=40, deadline=None)
@given(log2_scale=st.integers(-60, 60), seed=st.integers(0, 2**16), period_ms=st.floats(4.0, 25.0))
def test_scale_invariant_finite_and_bounded(log2_scale, seed, period_ms):
    config = get_preset("paper").config
    x = _flash_train(config, 600, period_ms * 1e-3, seed)
    a = envelope.autocorrelation(x, config, np.zeros(1))
    b = envelope.autocorrelation((x.astype(np.complex128) * 2.0 ** log2_scale), config, np.zeros(1))
    assert a.dtype == np.float32 and np.all(np.isfinite(b)) and np.all(np.abs(b) <= 1.0)
    np.testing.assert_allclose(a, b, atol=1e-4)


def test_an_all_zero_or_constant_return_gives_zeros():
    config = get_preset("paper").config
    for x in (np.zeros((1, 600, 3), np.complex64), np.ones((1, 600, 3), np.complex64)):
        assert not envelope.autocorrelation(x, config, np.zeros(1)).any()


@pytest.mark.parametrize("backend", ["numpy", "scipy"])
def test_the_feature_paths_spectrogram_gives_the_reference_values(backend: str) -> None:
    """The feature path feeds its own batched float32 STFT to `from_spectrogram`; it agrees with
    the float64 reference, moving body lines included."""
    from signatures.dsp.extraction import _spectrogram

    config = get_preset("paper").config
    x = np.concatenate([_flash_train(config, 600, p * 1e-3, seed=i) for i, p in enumerate((7.0, 11.0, 14.0))])
    body = np.array([0.0, 2 * 4.0 / config.wavelength_m, -2 * 9.0 / config.wavelength_m])
    win, hop = envelope.frames(config, 600)
    power, _ = _spectrogram(x, config, win, hop, backend)
    np.testing.assert_allclose(envelope.from_spectrogram(power, config, body, hop),
                               envelope.autocorrelation(x, config, body), atol=2e-4)
