"""Bundles: numpy arrays + ONNX + model card, digest check, reproducible training, sklearn-free inference."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from signatures.classify.inference import Classifier, NoModelError, load_classifier, match_preset
from core.digest import file_sha256
from signatures.classify.modelcard import ModelIntegrityError, read_card
from signatures.radar import get_preset
from signatures.train.training import train_bundle
from tests.classifiers.conftest import tiny_config
from tests.classifiers.standin import standin_extract

ROOT = Path(__file__).resolve().parents[2]


def test_card_lists_every_file_with_its_digest(tiny_bundle: Path) -> None:
    card, digest = read_card(tiny_bundle)
    assert set(card["files"]) == {p.name for p in tiny_bundle.iterdir()} - {"card.json"}
    for name, sha in card["files"].items():
        assert file_sha256(tiny_bundle / name) == sha
    assert card["preset"] == "paper" and card["classes"][-2:] == ["bird", "none"]
    assert card["training"]["seed"] == 3 and card["training"]["n_train"] == 200
    assert "scikit-learn" in card["libraries"] and len(digest) == 64
    assert not any(p.suffix in (".pkl", ".joblib", ".pickle") for p in tiny_bundle.iterdir())


@pytest.mark.parametrize("victim", ["rf.npz", "svm.npz", "openset.npz", "card.json"])
def test_tampered_bundle_is_refused(tiny_bundle: Path, tmp_path: Path, victim: str) -> None:
    bad = tmp_path / "bad"
    shutil.copytree(tiny_bundle, bad)
    data = bytearray((bad / victim).read_bytes())
    if victim == "card.json":
        card = json.loads(data)
        card["files"]["knn.npz"] = "0" * 64
        data = bytearray(json.dumps(card).encode())
    else:
        data[len(data) // 2] ^= 0xFF
    (bad / victim).write_bytes(bytes(data))
    with pytest.raises(ModelIntegrityError, match="does not match its model card"):
        Classifier(bad)


def test_missing_file_is_refused(tiny_bundle: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad"
    shutil.copytree(tiny_bundle, bad)
    (bad / "svm.npz").unlink()
    with pytest.raises(ModelIntegrityError, match="missing"):
        Classifier(bad)


def test_predict_one_return(tiny_bundle: Path) -> None:
    from signatures.sim.scene import Scene
    from signatures.sim.simulate import simulate
    from signatures.profiles import shipped_profiles

    clf = load_classifier(path=tiny_bundle)
    assert load_classifier(path=tiny_bundle) is clf  # loaded once per process
    scene = Scene(kind="uav", profile=shipped_profiles()["m600"], range_m=300, snr_db=20)
    rec, _ = simulate(scene, get_preset("paper"), 5)
    res = standin_extract(rec)
    pred = clf.predict(res.as_array(), res.rd_patch)
    assert pred.label in (*clf.classes, "unknown") and 0 < pred.confidence <= 1
    assert abs(sum(pred.probabilities.values()) - 1) < 1e-6
    assert pred.known == (pred.label != "unknown") and pred.nearest in clf.classes
    with pytest.raises(Exception, match="expects"):
        clf.predict(np.zeros(3))


def test_cascade_runs_cnn_only_below_threshold(tiny_bundle: Path) -> None:
    clf = load_classifier(path=tiny_bundle)
    assert clf.has_cnn
    rng = np.random.default_rng(0)
    X = rng.normal(size=(50, clf.n_features)).astype(np.float32)
    rd = rng.normal(size=(50, 32, 32)).astype(np.float32)
    p_ens = clf.ensemble_proba(X)
    clf.cascade_threshold, saved = 0.999, clf.cascade_threshold
    try:
        p, used = clf.cascade_proba(X, rd)
        np.testing.assert_array_equal(used, p_ens.max(1) < 0.999)
        np.testing.assert_allclose(p[~used], p_ens[~used])
        np.testing.assert_allclose(p[used], 0.5 * (p_ens[used] + clf.cnn_proba(rd[used])), rtol=1e-5)
        _, none_used = clf.cascade_proba(X, None)  # no RD patch: ensemble alone
        assert not none_used.any()
        calls = []
        p_lazy, _ = clf.cascade_proba(X, lambda: calls.append(1) or rd)  # patches built only when needed
        np.testing.assert_allclose(p_lazy, p)
        assert calls == ([1] if used.any() else [])
        clf.cascade_threshold = 0.0
        clf.cascade_proba(X, lambda: calls.append(2) or rd)
        assert 2 not in calls
    finally:
        clf.cascade_threshold = saved


def test_numpy_forests_match_scikit_learn(tiny_bundle: Path) -> None:
    metrics = read_card(tiny_bundle)[0]["metrics"]["validation"]
    assert metrics["forest_max_abs_error"] < 1e-6  # rf.npz / rf_state.npz vs predict_proba on validation
    assert 0.5 < metrics["state_accuracy"] <= 1.0


def test_forest_arrays_against_scikit_learn_on_random_data(tmp_path: Path) -> None:
    from sklearn.ensemble import RandomForestClassifier

    from signatures.train.classifiers import forest_arrays
    from signatures.classify.members import ForestArrays

    rng = np.random.default_rng(1)
    X = rng.normal(size=(400, 6)).astype(np.float32)
    y = (X[:, 0] + X[:, 1] ** 2 > 0.5).astype(int) + 2 * (X[:, 2] > 1.0)  # classes 0, 1, 2, 3
    rf = RandomForestClassifier(n_estimators=20, random_state=0).fit(X, y)
    np.savez(tmp_path / "rf.npz", **forest_arrays(rf, 5))  # one class never seen: column of zeros
    Xt = rng.normal(size=(300, 6)).astype(np.float32) * 3
    p = ForestArrays(tmp_path / "rf.npz").predict_proba(Xt)
    np.testing.assert_allclose(p[:, :4], rf.predict_proba(Xt), atol=1e-6)
    assert np.all(p[:, 4] == 0)


def test_training_is_reproducible(tiny_bundle: Path, tmp_path: Path, cache_dir: Path) -> None:
    again = tmp_path / "paper"
    train_bundle(tiny_config(), again, standin_extract, cache=cache_dir)
    assert (again / "card.json").read_bytes() == (tiny_bundle / "card.json").read_bytes()


def test_enrolled_profile_needs_no_code(tmp_path: Path, cache_dir: Path) -> None:
    card = train_bundle(tiny_config(cnn=False, extra=True), tmp_path / "b", standin_extract, cache=cache_dir)
    assert "octo-x8" in card["classes"] and "cnn.onnx" not in card["files"]
    assert load_classifier(path=tmp_path / "b").classes == tuple(card["classes"])


def test_inference_imports_neither_sklearn_nor_torch(tiny_bundle: Path) -> None:
    code = ("import sys, numpy as np; from signatures.classify.inference import load_classifier; "
            f"c = load_classifier(path={str(tiny_bundle)!r}); c.predict(np.zeros(c.n_features), np.zeros((32, 32))); "
            "bad = [m for m in ('sklearn', 'torch') if m in sys.modules]; assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def test_preset_is_matched_from_the_waveform() -> None:
    for name in ("paper", "wide"):
        pre = get_preset(name)
        assert match_preset(pre.with_offset(321.0), pre.n_chirps, pre.n_samples) == name
    pre = get_preset("paper")
    other = pre.config.replace(carrier_hz=24e9)
    with pytest.raises(NoModelError, match="no classifier for this waveform"):
        match_preset(other, pre.n_chirps, pre.n_samples)
    with pytest.raises(NoModelError):
        load_classifier(preset="nope")


def test_bundle_of_another_layout_is_refused_not_guessed(tiny_bundle: Path, tmp_path: Path) -> None:
    """No code default stands in for a value the bundle lacks: an open-set file without its
    tolerance parameters (an older layout) is refused with a rebuild hint."""
    from signatures.errors import SignaturesError
    from signatures.classify.modelcard import write_card

    old = tmp_path / "old"
    shutil.copytree(tiny_bundle, old)
    with np.load(old / "openset.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if not k.startswith("phys_param")}
    np.savez(old / "openset.npz", **arrays)
    card = json.loads((old / "card.json").read_text())
    write_card(old, {**card, "files": list(card["files"])})
    with pytest.raises(SignaturesError, match="phys_param_names.*authn models train"):
        Classifier(old)
