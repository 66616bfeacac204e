"""Waveforms as data: keys and names, radar-configuration files, dataset keys, bundle lookup."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from signatures.train.dataset import GENERATOR_VERSION, DatasetError, DatasetSpec, generate
from signatures.errors import SignaturesError
from signatures.classify.inference import NoModelError, classifier_for, find_bundle, load_classifier
from signatures.profiles import shipped_profiles
from signatures.radar import PRESETS, C, get_preset, load_waveform, parse_waveform, waveform_of
from signatures.train.training import TrainConfig, train_bundle
from tests.classifiers.standin import standin_extract

PAPER = get_preset("paper")
PROFILES = tuple(shipped_profiles().values())


def _cut(n_chirps: int = 512, domain: str = "if", **config):
    """The paper waveform with another chirp count (and config changes)."""
    return waveform_of(PAPER.config.replace(**config), n_chirps, PAPER.n_samples, domain)


def _rec(wf, offset: float = 300.0, domain: str | None = None) -> SimpleNamespace:
    """What bundle lookup reads of a Recording (no IQ needed)."""
    return SimpleNamespace(config=wf.with_offset(offset), n_chirps=wf.n_chirps, n_samples=wf.n_samples,
                           domain=domain or wf.domain)


def test_shipped_presets_are_found_by_their_waveform() -> None:
    for name, pre in PRESETS.items():
        wf = waveform_of(pre.with_offset(412.0), pre.n_chirps, pre.n_samples)
        assert wf is pre and wf.shipped and find_bundle(wf).name == name
    assert waveform_of(PAPER.config, PAPER.n_chirps, PAPER.n_samples, "range") is PAPER  # the IF pipeline's spectrum
    assert not waveform_of(PAPER.config, PAPER.n_chirps, PAPER.n_samples, "cw").shipped


def test_another_waveform_is_named_after_its_parameters() -> None:
    wf = _cut()
    assert not wf.shipped and wf.name == f"77GHz-512x80-{wf.key[:8]}"
    assert wf.describe() == "512x80 at 77 GHz, PRI 44 us"
    assert wf.key != PAPER.key and len({wf.key, _cut(domain="cw").key, _cut(carrier_hz=24e9).key}) == 3
    assert _cut(domain="cw").name.startswith("77GHz-cw-512x80-")
    assert "cw domain" in _cut(domain="cw").describe()


@settings(max_examples=60, deadline=None)
@given(offset=st.floats(0, 5000), rel=st.floats(-5e-7, 5e-7), chirps=st.integers(16, 4096))
def test_matching_ignores_the_range_gate_and_rounding(offset: float, rel: float, chirps: int) -> None:
    wf = _cut(chirps)
    # ramp_s moves with pri_s: the paper's chirps are back to back, and a config with pri_s < ramp_s
    # is refused on construction (replace checks it)
    cfg = wf.config.replace(range_offset_m=offset, pri_s=wf.config.pri_s * (1 + rel),
                            ramp_s=wf.config.ramp_s * (1 + rel))
    assert wf.matches(cfg, chirps, wf.n_samples)
    assert waveform_of(wf.with_offset(offset), chirps, wf.n_samples).key == wf.key
    assert not wf.matches(cfg, chirps, wf.n_samples, "cw")
    assert not wf.matches(cfg.replace(pri_s=wf.config.pri_s * 1.002), chirps, wf.n_samples)  # beyond 1e-3


def test_radar_configuration_file_round_trips(tmp_path: Path) -> None:
    wf = _cut()
    path = tmp_path / "radar.json"
    path.write_text(json.dumps({**wf.as_json(), "range_offset_m": 120.0}))
    back = load_waveform(path)
    assert (back.name, back.key, back.max_range_m, back.domain) == (wf.name, wf.key, wf.max_range_m, "if")
    assert back.config.range_offset_m == 0.0


@pytest.mark.parametrize("change,needle", [
    ({"n_chirps": None}, "n_chirps"),
    ({"carrier_hz": "fast"}, "carrier_hz"),
    ({"carrier_hz": -1.0}, "carrier_hz"),
    ({"pri_s": 1e-6}, "chirps would overlap"),
    ({"chirp_count": 3}, "chirp_count"),
    ({"domain": "pulse"}, "domain"),
    ({"n_samples": 4}, "n_samples"),
    ({"max_range_m": 10.0}, "max_range_m"),
])
def test_bad_radar_configuration_is_one_line(tmp_path: Path, change: dict, needle: str) -> None:
    doc = {k: v for k, v in {**_cut().as_json(), **change}.items() if v is not None}
    path = tmp_path / "radar.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(SignaturesError, match=needle) as err:
        load_waveform(path)
    assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)


def test_unreadable_radar_configuration(tmp_path: Path) -> None:
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(SignaturesError, match="not JSON"):
        load_waveform(tmp_path / "x.json")
    with pytest.raises(SignaturesError, match="cannot read"):
        load_waveform(tmp_path / "missing.json")


def _legacy_key(spec: DatasetSpec) -> str:
    """The cache key as computed before waveforms were data (preset as its name)."""
    doc = asdict(DatasetSpec(**{**spec.__dict__, "preset": "paper"}))
    del doc["nuisance"]  # the field came later; a spec without randomisation keeps the old key
    doc["preset"] = spec.waveform.name
    doc["profiles"] = [p.to_dict(json=True) for p in spec.profiles]
    doc["generator_version"] = GENERATOR_VERSION
    blob = json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()
    return hashlib.sha256(blob).hexdigest()[:24]


def test_dataset_keys_of_shipped_presets_are_unchanged_and_others_digest_the_waveform() -> None:
    for name in PRESETS:
        for kw in ({"split": "train", "n": 8000}, {"split": "test", "n": 300, "snr_db": 10.0}):
            by_name = DatasetSpec(preset=name, profiles=PROFILES, **kw)
            assert by_name.waveform is PRESETS[name]
            assert by_name.key() == DatasetSpec(preset=PRESETS[name], profiles=PROFILES, **kw).key()
            assert by_name.key() == _legacy_key(by_name)
    keys = {DatasetSpec(preset=wf, profiles=PROFILES, split="train", n=100).key()
            for wf in (PAPER, _cut(), _cut(513), _cut(carrier_hz=76e9))}
    far = waveform_of(_cut().config, 512, 80, max_range_m=800.0)
    keys.add(DatasetSpec(preset=far, profiles=PROFILES, split="train", n=100).key())
    assert len(keys) == 5


def test_a_cw_waveform_has_one_sample_per_pulse() -> None:
    with pytest.raises(DatasetError, match="a CW waveform records one sample per pulse, this one has 80"):
        DatasetSpec(preset=_cut(domain="cw"), profiles=PROFILES, split="train", n=10)


def test_cw_and_range_training_sets_are_simulated_in_their_domain() -> None:
    """A CW waveform's returns are CW cubes (no range: the range features are 0); a range
    waveform's are the IF pipeline's range spectra (the same features as the IF cube's)."""
    from signatures.sim.domain import cw_config

    cw = waveform_of(cw_config(PAPER.config.carrier_hz, PAPER.config.pri_s), 600, 1, "cw")
    data = generate(DatasetSpec(preset=cw, profiles=PROFILES, split="train", n=6), workers=1, cache=False)
    names = list(data.feature_names)
    for name in ("mean_range_m", "std_range_m"):
        assert np.all(data.X[:, names.index(name)] == 0)
    assert np.all(data.X[:, names.index("flash_rate_hz")][data.y == "m300"] > 0)
    rng_wf = waveform_of(PAPER.config, PAPER.n_chirps, PAPER.n_samples, "range")
    as_if = generate(DatasetSpec(preset=PAPER, profiles=PROFILES, split="train", n=4), workers=1, cache=False)
    as_range = generate(DatasetSpec(preset=rng_wf, profiles=PROFILES, split="train", n=4), workers=1, cache=False)
    np.testing.assert_allclose(as_range.X, as_if.X, rtol=1e-3, atol=1e-3)


@pytest.fixture(scope="module")
def user_models(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A models folder holding a tiny stand-in bundle for the 512-chirp paper waveform."""
    root = tmp_path_factory.mktemp("models")
    wf = _cut()
    cfg = TrainConfig(preset=wf, profiles=PROFILES, n_train=150, n_val=60, cnn=False, workers=1, n_test=10)
    train_bundle(cfg, root / wf.name, standin_extract, cache=tmp_path_factory.mktemp("cache"))
    return root


def test_user_bundle_card_describes_its_waveform(user_models: Path) -> None:
    wf = _cut()
    card = json.loads((user_models / wf.name / "card.json").read_text())
    assert card["preset"] == wf.name and card["waveform"]["key"] == wf.key
    assert parse_waveform(card["waveform"]["radar_config"], "card").key == wf.key
    assert card["radar"]["n_chirps"] == 512 and card["waveform"]["radar_config"]["domain"] == "if"
    # the physical check's Doppler bin is this waveform's (512 chirps), not the paper preset's (600)
    tip_bin = C / wf.config.carrier_hz / 2 / (wf.config.pri_s * 512)
    assert card["open_set"]["physics"]["tip_bin_mps"] == pytest.approx(tip_bin, abs=1e-6)
    assert card["open_set"]["physics"]["tip_bin_mps"] > 600 / 512 * 0.99 * PAPER.config.doppler_bin_mps(600)
    assert set(card["waveform"]["tips_alias_when_hovering"]) == {p.slug for p in PROFILES
                                                                 if wf.config.tip_aliases(p)}
    test = card["metrics"]["test"]
    assert set(test["per_snr"]) == {"0", "10", "20"} and test["n_per_snr"] == 10
    for row in test["per_snr"].values():
        assert 0 <= row["genuine_confirmed"] + row["wrong_airframe"] + row["called_unknown"] <= 1 + 1e-9


def test_lookup_prefers_shipped_then_user_bundles(user_models: Path, monkeypatch) -> None:
    monkeypatch.setenv("AUTHN_MODELS_DIR", str(user_models))
    wf = _cut()
    clf = classifier_for(_rec(wf))
    assert clf.folder == user_models / wf.name and clf.preset == wf.name and clf.waveform.key == wf.key
    assert classifier_for(_rec(wf, offset=900.0)) is clf  # kept for the process
    assert load_classifier(wf.name) is clf  # user bundles by name too
    assert classifier_for(_rec(PAPER)).preset == "paper"
    with pytest.raises(NoModelError, match=r"no classifier for this waveform \(513x80 at 77 GHz, PRI 44 us\): "
                                           r"build one with `authn models train --like x.h5`"):
        classifier_for(_rec(_cut(513)), source="x.h5")
    assert classifier_for(_rec(wf, domain="range")) is clf  # a range cube: the IF bundle's features
    with pytest.raises(NoModelError, match=r"no classifier for this waveform \(512x80 at 77 GHz.*cw domain\): build"):
        classifier_for(_rec(wf, domain="cw"))  # an IF bundle never serves a CW file


def test_explicit_bundle_must_serve_the_file(user_models: Path) -> None:
    wf = _cut()
    assert classifier_for(_rec(wf), model=user_models / wf.name).preset == wf.name
    with pytest.raises(NoModelError, match=r"this bundle is for 512x80 at 77 GHz.*the file's waveform is 600x80"):
        classifier_for(_rec(PAPER), model=user_models / wf.name)


def test_an_empty_models_folder_finds_nothing(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("AUTHN_MODELS_DIR", str(tmp_path / "none"))
    with pytest.raises(NoModelError, match="--like FILE"):
        find_bundle(_cut(640))
