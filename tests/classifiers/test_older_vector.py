"""A bundle trained on an earlier, shorter feature vector (before the flash envelope was appended,
e.g. a site's enrolment) reads its features from today's vector by name, and predicts exactly as
it does from its own vector."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from signatures.errors import SignaturesError
from signatures.dsp.feature_vector import ENVELOPE_FEATURES, FEATURE_NAMES
from signatures.features import extract
from signatures.classify.inference import Classifier
from signatures.train.training import train_bundle
from tests.classifiers.conftest import tiny_config
from tests.classifiers.standin import StandinResult
from tests.features.conftest import sim

OLDER = tuple(n for n in FEATURE_NAMES if n not in ENVELOPE_FEATURES)
KEEP = np.array([FEATURE_NAMES.index(n) for n in OLDER])


def older_vector(rec, expected_range_m=None) -> StandinResult:
    """Today's features without the flash envelope: the vector of FEATURE_VERSION 5."""
    res = extract(rec, expected_range_m)
    return StandinResult(res.as_array()[KEEP], res.rd_patch, OLDER)


@pytest.fixture(scope="module")
def older_bundle(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("older") / "paper"
    train_bundle(tiny_config(cnn=False), out, older_vector, cache=tmp_path_factory.mktemp("older-cache"))
    return out


def test_an_older_bundle_reads_todays_vector_by_name(older_bundle: Path) -> None:
    clf = Classifier(older_bundle)
    assert clf.feature_names == OLDER
    X = np.stack([extract(sim(model=m, radial_speed_mps=4.0, seed=s)[0]).as_array()
                  for m in ("m300", "m600", "phantom4") for s in (1, 2)])
    assert X.shape[1] == len(FEATURE_NAMES) > len(OLDER)
    today, own = clf.predict_many(X), clf.predict_many(X[:, KEEP])
    assert [p.label for p in today] == [p.label for p in own]
    assert [p.probabilities for p in today] == [p.probabilities for p in own]
    np.testing.assert_array_equal(clf.unknown_mask(X, np.zeros(len(X), int)),
                                  clf.unknown_mask(X[:, KEEP], np.zeros(len(X), int)))
    with pytest.raises(SignaturesError, match="model expects"):
        clf.predict_many(X[:, :-1])
