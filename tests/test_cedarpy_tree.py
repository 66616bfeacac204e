"""Deciding never imports cedarpy's policy-tree module (`authn.cedarpy_tree`), and reading that
module still gives the real one, whichever way it is read. Each case runs in a fresh process
(cedarpy is imported once per process)."""

from __future__ import annotations

import subprocess
import sys

import pytest

DECIDE = """
import json, sys
from authn import cedarpy_tree
from authn.policy import PolicyEngine
engine = PolicyEngine.load()
print(json.dumps({"deferred": cedarpy_tree.deferred(), "defined": sorted(vars(sys.modules["cedarpy.pst"]))}))
"""

READS = {
    "attribute": "import cedarpy; node = cedarpy.policies_to_pst('permit(principal, action, resource);'); "
                 "assert isinstance(node, cedarpy.pst.PolicySet), type(node)",
    "from-import": "from cedarpy.pst import PolicySet; import cedarpy; assert cedarpy.pst.PolicySet is PolicySet",
    "star-import": "from cedarpy.pst import *; assert 'PolicySet' in dir()",
    "import-as": "import cedarpy.pst as p; import sys; assert p.PolicySet is sys.modules['cedarpy.pst'].PolicySet",
}


def _run(code: str) -> str:
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_deciding_leaves_the_policy_tree_unimported() -> None:
    import json

    report = json.loads(_run(DECIDE).strip().splitlines()[-1])
    assert report["deferred"], report
    assert "PolicySet" not in report["defined"]


@pytest.mark.parametrize("how", sorted(READS))
def test_reading_the_policy_tree_imports_the_real_module(how: str) -> None:
    _run("from authn.policy import PolicyEngine\nfrom authn import cedarpy_tree\n" + READS[how] + "\n"
         "assert not cedarpy_tree.deferred()\nimport sys, cedarpy\nassert cedarpy.pst is sys.modules['cedarpy.pst']")
