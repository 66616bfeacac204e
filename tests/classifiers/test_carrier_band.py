"""One bundle for a band of carriers: exact carrier first, then the nearest within +-2.5 %,
outside it the no-model error; the Doppler-frequency features rescaled to the bundle's carrier."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from signatures.classify.carrier import CARRIER_BAND_REL, carrier_band_hz, carrier_ratio, normalise
from signatures.features import FEATURE_NAMES
from signatures.classify.inference import (NoModelError, classifier_for, find_bundle, load_classifier,
                                           waveform_differences)
from signatures.profiles import shipped_profiles
from signatures.radar import PRESETS, C, get_preset, waveform_of
from signatures.train.training import TrainConfig, train_bundle
from tests.classifiers.standin import standin_extract

PAPER = PRESETS["paper"]
CW = get_preset("cw-sband")


def _at(pre, carrier_hz: float, n_chirps: int | None = None):
    cfg = pre.config.replace(carrier_hz=carrier_hz)
    return waveform_of(cfg, n_chirps or pre.n_chirps, pre.n_samples, pre.domain, pre.max_range_m)


def _rec(wf) -> SimpleNamespace:
    """What bundle lookup reads of a Recording (no IQ needed)."""
    return SimpleNamespace(config=wf.with_offset(0.0), n_chirps=wf.n_chirps, n_samples=wf.n_samples, domain=wf.domain)


def test_band_is_stated_and_covers_a_radar_hopping_over_3_30_to_3_40_ghz() -> None:
    bundle = _at(CW, 3.35e9)
    lo, hi = carrier_band_hz(bundle)
    assert CARRIER_BAND_REL == 0.025 and lo < 3.30e9 and hi > 3.40e9
    for f in (3.30e9, 3.35e9, 3.40e9):
        assert carrier_ratio(bundle, _at(CW, f)) == pytest.approx(f / 3.35e9)
    assert carrier_ratio(bundle, _at(CW, 3.35e9 * 1.026)) is None  # outside the band
    other = waveform_of(bundle.config.replace(carrier_hz=3.36e9, pri_s=2.5e-4, ramp_s=2.5e-4,
                                                  bandwidth_hz=4e3, sample_rate_hz=4e3),
                        4096, 1, "cw")
    assert carrier_ratio(bundle, other) is None  # only the carrier may differ
    assert carrier_ratio(bundle, _at(CW, 3.35e9, 2048)) is None
    assert waveform_differences(bundle, _at(CW, 3.38e9)) == []  # serving means no difference left
    assert [d[0] for d in waveform_differences(bundle, _at(CW, 3.5e9))] == ["carrier_hz"]


def test_a_shipped_bundle_serves_its_band_and_refuses_beyond_it(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("AUTHN_MODELS_DIR", str(tmp_path / "none"))
    assert find_bundle(_at(PAPER, 78.5e9)).name == "paper"  # +1.9 %
    assert classifier_for(_rec(_at(PAPER, 75.5e9))).preset == "paper"
    with pytest.raises(NoModelError, match=r"no classifier for this waveform \(600x80 at 79 GHz.*--like x\.h5.*"
                                           r"nearest bundle paper differs in carrier_hz 77000000000\.0 there, "
                                           r"79000000000\.0 here, carrier band \+-2\.5%"):
        find_bundle(_at(PAPER, 79e9), "x.h5")
    wide = PRESETS["wide"]
    assert classifier_for(_rec(_at(wide, 77.5e9)), model=Path(find_bundle(wide))).preset == "wide"
    with pytest.raises(NoModelError, match=r"this bundle is for 8192x64 at 77 GHz, PRI 6.25 us "
                                           r"\(carrier band \+-2.5%\)"):
        classifier_for(_rec(_at(wide, 80e9)), model=find_bundle(wide))


@pytest.fixture(scope="module")
def band_models(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A models folder with two tiny stand-in CW bundles' cards: one trained at 3.35 GHz and a copy
    whose card says 3.38 GHz (lookup reads cards only; nothing here is loaded)."""
    root = tmp_path_factory.mktemp("models")
    wf = _at(CW, 3.35e9, 128)
    cfg = TrainConfig(preset=wf, profiles=tuple(shipped_profiles().values()), n_train=150, n_val=60, cnn=False,
                      workers=1)
    train_bundle(cfg, root / wf.name, standin_extract, cache=tmp_path_factory.mktemp("cache"))
    shutil.copytree(root / wf.name, root / "a-copy-at-3.38")
    card_path = root / "a-copy-at-3.38" / "card.json"
    card = json.loads(card_path.read_text())
    card["waveform"]["radar_config"]["carrier_hz"] = 3.38e9
    card_path.write_text(json.dumps(card))
    return root


def test_exact_carrier_first_then_the_nearest_within_the_band(band_models: Path, monkeypatch) -> None:
    monkeypatch.setenv("AUTHN_MODELS_DIR", str(band_models))
    at335 = band_models / _at(CW, 3.35e9, 128).name
    assert find_bundle(_at(CW, 3.35e9, 128)) == at335
    assert find_bundle(_at(CW, 3.38e9, 128)) == band_models / "a-copy-at-3.38"  # exact, though sorted after
    assert find_bundle(_at(CW, 3.30e9, 128)) == at335
    assert find_bundle(_at(CW, 3.37e9, 128)) == band_models / "a-copy-at-3.38"  # nearer 3.38 than 3.35
    assert find_bundle(_at(CW, 3.46e9, 128)) == band_models / "a-copy-at-3.38"  # 2.4 % from 3.38
    with pytest.raises(NoModelError, match=r"no classifier for this waveform \(128x1 at 3.2 GHz"):
        find_bundle(_at(CW, 3.2e9, 128))  # 4.5 % below 3.35


def test_the_cli_refuses_a_carrier_outside_the_band_with_exit_2(band_models: Path, tmp_path: Path,
                                                                 monkeypatch, capsys) -> None:
    from authn.cli import main

    monkeypatch.setenv("AUTHN_MODELS_DIR", str(band_models))
    serial = "1581BDEM00000002"
    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    assert main(["--db", db, "register", "--serial", serial, "--model", "m300"]) == 0
    for carrier in ("3.2e9", "3.30e9"):
        flight = tmp_path / f"cw_{carrier}.h5"
        assert main(["simulate", "--model", "m300", "--range", "300", "--snr", "20", "--preset", "cw-sband",
                     "--chirps", "128", "--carrier", carrier, "--rid-serial", serial, "--out", str(flight)]) == 0
        capsys.readouterr()
        got = main(["--db", db, "check", str(flight), "--serial", serial])
        err = capsys.readouterr().err
        if carrier == "3.2e9":
            assert got == 2 and "no classifier for this waveform (128x1 at 3.2 GHz" in err \
                and "carrier band +-2.5%" in err, err
        else:  # the 3.35 GHz bundle is found (its stand-in features then fail the check: not the lookup's error)
            assert "no classifier" not in err, err


def _aliased_row(names: list[str]) -> np.ndarray:
    x = np.zeros(len(names), dtype=np.float32)
    x[names.index("spectral_centroid_hz")], x[names.index("spectral_bandwidth_hz")] = 1000.0, 400.0
    x[names.index("flash_rate_hz")], x[names.index("cadence_peak_hz")] = 120.0, 120.0
    x[names.index("std_doppler_mps")], x[names.index("tip_speed_mps")] = 20.0, 60.0
    return x


def test_a_recording_at_1_02_times_the_carrier_reads_its_hz_features_1_02_lower() -> None:
    names = list(FEATURE_NAMES)
    x = np.stack([_aliased_row(names)] * 2)
    x[1, names.index("tip_aliased")] = 1.0
    cw = _at(CW, 3.35e9)
    y = normalise(x, names, cw.config, 1, 3.35e9 * 1.02)
    for n in ("spectral_centroid_hz", "spectral_bandwidth_hz"):
        np.testing.assert_allclose(y[:, names.index(n)], x[:, names.index(n)] / 1.02, rtol=1e-6)
    moved = [n for i, n in enumerate(names) if not np.allclose(y[:, i], x[:, i])]
    assert moved == ["spectral_centroid_hz", "spectral_bandwidth_hz", "tip_speed_mps"]
    tip = names.index("tip_speed_mps")
    assert y[0, tip] == x[0, tip]  # a measured tip speed (m/s) is wavelength-free
    # an aliased one is the band's edge lambda PRF / 4 - |v|: the bundle's longer wavelength reads it higher
    shift = (C / 3.35e9 - C / (3.35e9 * 1.02)) * cw.config.prf_hz / 4
    assert y[1, tip] == pytest.approx(x[1, tip] + shift, rel=1e-6) and shift > 0
    assert normalise(x, names, cw.config, 1, 3.35e9) is x  # the bundle's own carrier: untouched
    assert normalise(x, ["centroid", "bandwidth"], cw.config, 1, 3.4e9) is x  # no Doppler-frequency feature


def test_the_classifier_sees_features_on_its_own_carrier() -> None:
    clf = load_classifier("paper")
    names = list(clf.feature_names)
    x = _aliased_row(names)[None, :]
    f = 77e9 * 1.02
    y = clf.on_carrier(x, f)
    # FMCW: the Doppler wavelength is the sweep's mid frequency's, 75 MHz above the carrier at 77 GHz
    ratio = (77e9 + 75e6 * 79 / 80) / (f + 75e6 * 79 / 80)
    i = names.index("spectral_centroid_hz")
    assert y[0, i] == pytest.approx(1000.0 * ratio, rel=1e-5) and y[0, i] < 1000.0 / 1.0199
    assert clf.predict(x[0], carrier_hz=f) == clf.predict(y[0])
    assert clf.predict(x[0], carrier_hz=77e9) == clf.predict(x[0])
