"""The array-first blade-flash estimators (`signatures.dsp.flash_series`, `signatures.dsp.flash_period`) equal
the single-return reference (tests/features/reference_flash.py) row by row, on simulated
gates of both shipped presets (airframes, birds, noise only; hovering and moving; -5..30 dB)
and on edge cases (all zero, no events, one row, chirps shorter than the high-pass, 2 columns)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from signatures.dsp import flash_period, flash_series
from signatures.dsp.flash_period import PeriodicityBatch, periodicity_batch
from signatures.dsp.flash_series import flash_series_batch
from signatures.errors import SignaturesError
from signatures.radar import get_preset
from lab.flash_gates import Gate, simulated_gates
from tests.features import reference_flash as ref

CONTINUOUS = ("flash_rate_hz", "flash_rate_std_hz", "score", "flash_par_db", "rotor_count_std", "rotors_seen",
              "rotors_seen_std")
EXACT = ("n_events", "rotor_count")


@pytest.fixture(scope="module")
def paper_gates() -> list[Gate]:
    return simulated_gates("paper", 120)


@pytest.fixture(scope="module")
def wide_gates() -> list[Gate]:
    return simulated_gates("wide", 30)


def reference(slow: np.ndarray, config, body_hz: np.ndarray, bin_m: float, n_fft: int) -> dict[str, np.ndarray]:
    """The single-return path, row by row."""
    rows = []
    for b in range(slow.shape[0]):
        per = ref.periodicity(ref.flash_series(slow[b], config, float(body_hz[b]), bin_m, n_fft))
        rot = ref.rotor_count(per)
        rows.append((per.flash_rate.value, per.flash_rate.std, per.score, per.n_events, per.flash_par_db,
                     rot.value, rot.std, per.rotors_seen.value, per.rotors_seen.std))
    names = ("flash_rate_hz", "flash_rate_std_hz", "score", "n_events", "flash_par_db", "rotor_count",
             "rotor_count_std", "rotors_seen", "rotors_seen_std")
    return {name: np.array([r[i] for r in rows]) for i, name in enumerate(names)}


def assert_batch_matches(slow: np.ndarray, config, body_hz: np.ndarray, bin_m: float,
                         n_fft: int) -> PeriodicityBatch:
    """`periodicity_batch` against the single-return reference, row by row."""
    want = reference(slow, config, body_hz, bin_m, n_fft)
    series = flash_series_batch(slow, config, body_hz, bin_m, n_fft)
    for got in (periodicity_batch(series),):
        for name in EXACT:
            np.testing.assert_array_equal(getattr(got, name), want[name], err_msg=name)
        for name in CONTINUOUS:
            v, w = getattr(got, name), want[name]
            assert np.all(np.abs(v - w) <= 1e-6 * np.maximum(np.abs(w), 1.0)), (name, v, w)
    return got


def stack(gates: list[Gate]) -> tuple[np.ndarray, np.ndarray]:
    return np.stack([g.slow for g in gates]), np.array([g.body_hz for g in gates])


def three_columns(gates: list[Gate]) -> list[Gate]:
    return [g for g in gates if g.slow.shape[1] == 3]


def test_simulated_gates_cover_the_stress_cases(paper_gates, wide_gates):
    for gates in (paper_gates, wide_gates):
        labels = {g.label for g in gates}
        assert {"m300", "m600", "phantom4", "bird", "none"} <= labels
        snr = [g.snr_db for g in gates]
        assert min(snr) < 5.0 and max(snr) > 20.0
        hovering = [abs(g.body_hz) < 50.0 for g in gates if g.label not in ("bird", "none")]
        assert any(hovering) and not all(hovering)


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_batch_equals_single_path_on_simulated_gates(preset, paper_gates, wide_gates):
    gates = three_columns(paper_gates if preset == "paper" else wide_gates)
    assert len(gates) >= 28
    slow, body = stack(gates)
    got = assert_batch_matches(slow, gates[0].config, body, gates[0].range_bin_m, gates[0].n_fft)
    # the gates exercise the estimator: periodic rows, several rotors, rows without events
    assert np.count_nonzero(got.flash_rate_hz > 0) >= 10
    assert np.count_nonzero(got.rotor_count >= 2) >= 3
    assert np.count_nonzero(got.n_events < 2) >= 1


def test_flash_series_rows_are_the_single_series_to_the_bit(paper_gates):
    gates = three_columns(paper_gates)[:12]
    slow, body = stack(gates)
    g = gates[0]
    series = flash_series_batch(slow, g.config, body, g.range_bin_m, g.n_fft)
    for b in range(len(gates)):
        one = ref.flash_series(slow[b], g.config, float(body[b]), g.range_bin_m, g.n_fft)
        row = ref.series_row(series, b)
        np.testing.assert_array_equal(row.energy, one.energy)
        np.testing.assert_array_equal(row.per_bin, one.per_bin)
        np.testing.assert_array_equal(row.field, one.field)
        assert (row.threshold, row.drift_bins_per_sample, row.rate_hz) == \
            (one.threshold, one.drift_bins_per_sample, one.rate_hz)


def test_row_order_and_batch_size_do_not_change_a_row(paper_gates):
    gates = three_columns(paper_gates)
    slow, body = stack(gates)
    g = gates[0]
    whole = periodicity_batch(flash_series_batch(slow, g.config, body, g.range_bin_m, g.n_fft))
    order = np.random.default_rng(3).permutation(len(gates))
    shuffled = periodicity_batch(flash_series_batch(slow[order], g.config, body[order], g.range_bin_m,
                                                          g.n_fft))
    np.testing.assert_array_equal(shuffled.flash_rate_hz, whole.flash_rate_hz[order])
    np.testing.assert_array_equal(shuffled.rotor_count, whole.rotor_count[order])
    for b in (0, len(gates) // 2):  # B = 1: what a single check runs
        one = periodicity_batch(flash_series_batch(slow[b:b + 1], g.config, body[b:b + 1],
                                                         g.range_bin_m, g.n_fft))
        assert one.flash_rate_hz[0] == whole.flash_rate_hz[b]
        assert one.n_events[0] == whole.n_events[b]


def test_small_chunks_give_the_same_rows(paper_gates, monkeypatch):
    gates = three_columns(paper_gates)[:10]
    slow, body = stack(gates)
    g = gates[0]
    whole = periodicity_batch(flash_series_batch(slow, g.config, body, g.range_bin_m, g.n_fft))
    monkeypatch.setattr(flash_series, "MEMORY_BUDGET_BYTES", 1)  # one row per chunk
    monkeypatch.setattr(flash_period, "MEMORY_BUDGET_BYTES", 1)  # one row per group
    monkeypatch.setattr(flash_series, "CHUNK_BYTES", 1)
    chunked = periodicity_batch(flash_series_batch(slow, g.config, body, g.range_bin_m, g.n_fft))
    for name in EXACT + CONTINUOUS:
        np.testing.assert_array_equal(getattr(chunked, name), getattr(whole, name))


def test_edge_cases(paper_gates):
    """All zero, real, noise only, one flash."""
    g = three_columns(paper_gates)[0]
    real = g.slow
    zero = np.zeros_like(real)
    rng = np.random.default_rng(5)
    noise = ((rng.standard_normal(real.shape) + 1j * rng.standard_normal(real.shape)) / math.sqrt(2)).astype(
        np.complex64)
    single_flash = noise.copy()
    single_flash[300] += 40.0  # one event: no period
    slow = np.stack([zero, real, noise, single_flash])
    body = np.array([0.0, g.body_hz, 123.0, -50.0])
    got = assert_batch_matches(slow, g.config, body, g.range_bin_m, g.n_fft)
    assert got.n_events[0] == 0 and got.flash_rate_hz[0] == 0.0 and got.flash_par_db[0] == 0.0
    assert got.n_events[3] >= 1


def test_two_column_gates(paper_gates):
    gates = three_columns(paper_gates)[:8]
    slow = np.stack([gt.slow[:, :2] for gt in gates])
    body = np.array([gt.body_hz for gt in gates])
    g = gates[0]
    got = assert_batch_matches(slow, g.config, body, g.range_bin_m, g.n_fft)
    assert np.any(got.n_events > 0)


@pytest.mark.parametrize("chirps", [5, 9, 40])
def test_short_dwells(chirps, paper_gates):
    """Fewer chirps than the high-pass length (9 in paper), and series too short for a period."""
    gates = three_columns(paper_gates)[:6]
    slow = np.stack([gt.slow[:chirps] for gt in gates])
    body = np.array([gt.body_hz for gt in gates])
    g = gates[0]
    assert_batch_matches(slow, g.config, body, g.range_bin_m, g.n_fft)


def test_decimated_coherent_path(paper_gates):
    """A PRF of 52 kHz decimates by 2 and still runs the coherent checks (flash within one PRI)."""
    base = get_preset("paper").config
    config = type(base)(**{**base.__dict__, "pri_s": 1.0 / 52_000.0, "ramp_s": 1.0 / 52_000.0})
    dec = max(1, int(config.prf_hz // flash_series.SERIES_RATE_HZ))
    assert dec == 2 and config.prf_hz * flash_series.flash_lobe_s(config.wavelength_m) <= 1.0
    gates = three_columns(paper_gates)[:10]
    slow, body = stack(gates)
    series = flash_series_batch(slow, config, body, gates[0].range_bin_m, gates[0].n_fft)
    assert series.field is not None and series.decimation == 2
    assert_batch_matches(slow, config, body, gates[0].range_bin_m, gates[0].n_fft)


def test_wide_series_keeps_no_field(wide_gates):
    g = three_columns(wide_gates)[0]
    series = flash_series_batch(g.slow[None], g.config, np.array([g.body_hz]), g.range_bin_m, g.n_fft)
    assert series.field is None and series.decimation == 6  # flashes span chirps: no coherent checks


def test_bad_shapes_raise_one_line():
    config = get_preset("paper").config
    with pytest.raises(SignaturesError, match=r"B, chirps, \[windows,\] bins"):
        flash_series_batch(np.zeros((600, 3), np.complex64), config, np.zeros(1), 0.1, 80)
    with pytest.raises(SignaturesError, match="body_hz"):
        flash_series_batch(np.zeros((2, 600, 3), np.complex64), config, np.zeros(3), 0.1, 80)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_rows=st.integers(1, 4), flashes=st.integers(0, 40),
       period=st.floats(60.0, 300.0), amp=st.floats(0.5, 30.0), body=st.floats(-3000.0, 3000.0))
def test_synthetic_flash_trains(seed, n_rows, flashes, period, amp, body):
    """Noise with impulsive flash trains of random period, phase and amplitude."""
    config = get_preset("paper").config
    rng = np.random.default_rng(seed)
    n = 600
    slow = ((rng.standard_normal((n_rows, n, 3)) + 1j * rng.standard_normal((n_rows, n, 3))) / math.sqrt(2))
    t = np.arange(n)
    for b in range(n_rows):
        start = rng.uniform(0.0, period)
        for f in range(flashes):
            c = int(round(start + f * period * (1.0 + 0.3 * b)))
            if c >= n:
                break
            slow[b, c] += amp * np.exp(1j * rng.uniform(0, 2 * math.pi)) * np.array([0.5, 1.0, 0.4])
        slow[b] *= np.exp(2j * math.pi * body * config.pri_s * t)[:, None]
    body_hz = body + np.arange(n_rows) * 17.0
    assert_batch_matches(slow.astype(np.complex64), config, body_hz, 0.2, 80)


def test_complex128_gates(paper_gates):
    """complex128 gates (a caller's choice of precision) give the reference's rows too."""
    gates = three_columns(paper_gates)[:10]
    slow, body = stack(gates)
    g = gates[0]
    series = flash_series_batch(slow.astype(np.complex128), g.config, body, g.range_bin_m, g.n_fft)
    assert series.field is not None and series.field.dtype == np.complex128
    assert_batch_matches(slow.astype(np.complex128), g.config, body, g.range_bin_m, g.n_fft)
