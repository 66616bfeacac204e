"""Waveform matching is relative (`signatures.radar.WAVEFORM_REL_TOL`): a dwell at 5000.0 Hz is
served by a bundle made at 5000.1 Hz (2e-5 apart: the same radar's clock), one at 5100.0 Hz is
not, and the mismatch message starts with the parameter that differs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from signatures.classify.inference import NoModelError, find_bundle, waveform_differences
from signatures.radar import WAVEFORM_REL_TOL, get_preset, waveform_of

CW = get_preset("cw-sband")


def _clocked(rate_hz: float):
    """The S-band CW waveform with its clock at `rate_hz` (PRI, ramp and bandwidth follow it)."""
    pri = 1.0 / rate_hz
    cfg = CW.config.replace(sample_rate_hz=rate_hz, pri_s=pri, ramp_s=pri, bandwidth_hz=rate_hz)
    return waveform_of(cfg, CW.n_chirps, CW.n_samples, "cw", CW.max_range_m)


def _user_bundle(root: Path, wf) -> Path:
    """A user bundle folder whose card describes `wf` (lookup reads only the card)."""
    folder = root / wf.name
    folder.mkdir(parents=True)
    (folder / "card.json").write_text(json.dumps({"waveform": {"radar_config": wf.as_json()}}))
    return folder


def test_a_2e_5_clock_difference_is_the_same_radar(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("AUTHN_MODELS_DIR", str(tmp_path))
    bundle, dwell = _clocked(5000.1), _clocked(5000.0)
    assert bundle.key != dwell.key  # named apart (6 digits), served alike
    assert WAVEFORM_REL_TOL == 1e-3 and waveform_differences(bundle, dwell) == []
    assert bundle.matches(dwell.config, dwell.n_chirps, dwell.n_samples, "cw")
    folder = _user_bundle(tmp_path, bundle)
    assert find_bundle(dwell) == folder


def test_a_mismatch_message_starts_with_the_parameter_that_differs(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("AUTHN_MODELS_DIR", str(tmp_path))
    bundle = _clocked(5100.0)
    _user_bundle(tmp_path, bundle)
    with pytest.raises(NoModelError) as err:
        find_bundle(_clocked(5000.0), "x.h5")
    text = str(err.value)
    assert text.startswith(f"sample rate 5000.0 Hz here, 5100.0 Hz in bundle {bundle.name}: "), text
    assert "no classifier for this waveform" in text and "--like x.h5" in text


def test_an_active_site_bundle_made_at_5000_1_hz_serves_a_5000_0_hz_dwell(tmp_path: Path, monkeypatch) -> None:
    from signatures.classify.inference import active_bundle, set_active

    monkeypatch.setenv("AUTHN_MODELS_DIR", str(tmp_path))
    bundle = _clocked(5000.1)
    folder = tmp_path / "site-a"
    folder.mkdir()
    (folder / "card.json").write_text(json.dumps({"waveform": {"radar_config": bundle.as_json()}, "enrolment": {}}))
    set_active(bundle.key, "site-a")
    assert active_bundle(_clocked(5000.0)) == folder
    assert active_bundle(_clocked(5100.0)) is None
