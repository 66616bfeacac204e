"""The stress suite in reduced form: no crash, no NaN/Inf, no scale-dependent decision."""

from __future__ import annotations

import pytest

from authn.stress import run


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
