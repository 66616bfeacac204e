"""The regression corpus, built once per test session (about a second)."""

from __future__ import annotations

import pytest

from tests.fuzz.corpus import build_corpus


@pytest.fixture(scope="session")
def corpus(tmp_path_factory):
    return build_corpus(tmp_path_factory.mktemp("fuzz-corpus"))
