"""The shipped bundles: digests match their cards, and a quick accuracy sanity on fresh returns."""

from __future__ import annotations

import numpy as np
import pytest

from signatures.classify.inference import bundle_dir, load_classifier
from signatures.classify.modelcard import read_card


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_shipped_bundle_passes_its_digest_check(preset: str) -> None:
    folder = bundle_dir(preset)
    card, digest = read_card(folder)
    assert card["preset"] == preset and len(digest) == 64
    assert sum((folder / f).stat().st_size for f in card["files"]) < 8_000_000
    assert set(card["classes"]) >= {"m600", "m300", "phantom4", "bird", "none"}


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_shipped_bundle_classifies_fresh_returns(preset: str) -> None:
    from signatures.train.dataset import DatasetSpec, generate
    from signatures.profiles import UavProfile

    clf = load_classifier(preset)
    profiles = tuple(UavProfile.from_dict(p) for p in clf.card["profiles"])
    ds = generate(DatasetSpec(preset=preset, profiles=profiles, split="test", n=25, seed=99_999, snr_db=20.0),
                  workers=1, cache=False)
    labels = [clf.predict(x, rd).label for x, rd in zip(ds.X, ds.rd)]
    assert np.mean(np.array(labels) == ds.y) >= 0.8


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_shipped_ensemble_never_imports_onnxruntime(preset: str) -> None:
    """kNN, forests and the SVM are numpy arrays: a check whose ensemble is sure (no CNN) never
    imports onnxruntime (~100 ms of a cold start), whichever members its card weighs (at least one
    shipped card weighs the SVM)."""
    import subprocess
    import sys

    assert any(load_classifier(p).weights[2] > 0.0 for p in ("paper", "wide"))
    code = ("import sys, numpy as np; from signatures.classify.inference import load_classifier; "
            f"c = load_classifier({preset!r}); c.predict(np.zeros(c.n_features)); "
            "assert 'onnxruntime' not in sys.modules, 'onnxruntime imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_shipped_openset_holds_what_inference_reads_and_every_tuned_value(preset: str) -> None:
    from signatures.classify.openset import PhysicsCheck

    folder = bundle_dir(preset)
    card = read_card(folder)[0]
    with np.load(folder / "openset.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    assert str(arrays["mode"]) == card["open_set"]["mode"] == "physics"
    assert not any(k.startswith("ref_") for k in arrays)  # the distance test is not shipped
    params = dict(zip((str(n) for n in arrays["phys_param_names"]), arrays["phys_param_values"].tolist()))
    assert set(params) == set(PhysicsCheck.SCALARS)
    phys = card["open_set"]["physics"]
    for name in ("z", "max_rel_tol", "min_flash_score", "min_rel_tol", "min_rel_tip_tol"):
        assert params[name] == phys[name]
    assert params["jitter"] == phys["rotor_rate_jitter"] and round(params["tip_bin_mps"], 6) == phys["tip_bin_mps"]
    assert arrays["phys_rate_slips"].tolist() == phys["aliased_rate_slips"]
