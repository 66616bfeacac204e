"""Tests that run the laboratory's commands through `authn` (`authn bench`, `authn features
accuracy|score`) need authn-lab installed, whose entry points plug them in (lab/pyproject.toml;
`pip install -e ./lab`, as .ci/run does). Without it they are skipped, by that reason."""

from __future__ import annotations

import pytest

from authn.cli.plugins import LAB_COMMANDS, installed

#: skip unless every laboratory command is registered by an installed distribution
needs_lab = pytest.mark.skipif(not LAB_COMMANDS <= set(installed()),
                               reason="authn-lab not installed (pip install -e ./lab): its commands are plugins")
