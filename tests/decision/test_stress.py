"""The stress suite in reduced form: no crash, no NaN/Inf, no scale-dependent decision."""

from __future__ import annotations

import pytest

from lab.bench.stress import run


@pytest.fixture(scope="module")
def report():
    return run(("paper",), quick=True)


def test_no_crashes(report) -> None:
    assert report.cases >= 25 and report.crashes == []


def test_features_always_finite(report) -> None:
    assert report.nonfinite == []


def test_nan_and_inf_are_refused(report) -> None:
    assert report.nan_inf_not_refused == []


def test_amplitude_scaling_never_changes_the_decision(report) -> None:
    assert report.scale_decision_changes == []


def test_only_specific_errors_are_unsupported_waveforms(report) -> None:
    assert all("no classifier for this waveform" in e for e in report.specific_errors)


def test_float32_transforms_match_float64_transforms(report) -> None:
    """Every case with features is compared; only ill-posed degenerate cubes (a single spike has
    a flat Doppler spectrum: its argmax is a tie) may leave the tolerance, and no label changes."""
    assert len(report.fft64_max_rel) == report.cases - 3  # all but the NaN/Inf files (refused on read)
    assert all("/degenerate/" in d for d in report.fft64_deviations)
    assert report.fft64_label_changes == []
