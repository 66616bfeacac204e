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
