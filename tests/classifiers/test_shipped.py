"""The shipped bundles: digests match their cards, and a quick accuracy sanity on fresh returns."""

from __future__ import annotations

import numpy as np
import pytest

from signatures.inference import bundle_dir, load_classifier
from signatures.modelcard import read_card


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_shipped_bundle_passes_its_digest_check(preset: str) -> None:
    folder = bundle_dir(preset)
    card, digest = read_card(folder)
    assert card["preset"] == preset and len(digest) == 64
    assert sum((folder / f).stat().st_size for f in card["files"]) < 8_000_000
    assert set(card["classes"]) >= {"m600", "m300", "phantom4", "bird", "none"}


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_shipped_bundle_classifies_fresh_returns(preset: str) -> None:
    from signatures.dataset import DatasetSpec, generate
    from signatures.profiles import UavProfile

    clf = load_classifier(preset)
    profiles = tuple(UavProfile.model_validate(p) for p in clf.card["profiles"])
    ds = generate(DatasetSpec(preset=preset, profiles=profiles, split="test", n=25, seed=99_999, snr_db=20.0),
                  workers=1, cache=False)
    labels = [clf.predict(x, rd).label for x, rd in zip(ds.X, ds.rd)]
    assert np.mean(np.array(labels) == ds.y) >= 0.8


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_shipped_ensemble_path_needs_no_onnxruntime(preset: str) -> None:
    """kNN and forests are numpy arrays; the shipped ensembles give the SVM no weight, so a check
    whose ensemble is sure (no CNN) never imports onnxruntime (~25 ms + ~9 ms per session)."""
    import subprocess
    import sys

    assert load_classifier(preset).weights[2] == 0.0
    code = ("import sys, numpy as np; from signatures.inference import load_classifier; "
            f"c = load_classifier({preset!r}); c.predict(np.zeros(c.n_features)); "
            "assert 'onnxruntime' not in sys.modules, 'onnxruntime imported'")
    subprocess.run([sys.executable, "-c", code], check=True)
