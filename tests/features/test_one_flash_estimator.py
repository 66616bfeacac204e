"""Each blade-flash estimator has one implementation in the product, array-first (one return is a
batch of one); the per-return form lives only in the tests, as the reference the product equals to
the bit (tests/features/reference_flash.py)."""

from __future__ import annotations

import ast
from pathlib import Path

import signatures

REFERENCE = Path(__file__).with_name("reference_flash.py")
#: The reference's per-return types and estimators: the product computes these only through the batch
#: forms (`FlashSeriesBatch`, `PeriodicityBatch`, `flash_series_batch`, `periodicity_batch`).
PER_RETURN_TYPES = {"FlashSeries", "Periodicity", "Estimate"}
PER_RETURN_ESTIMATORS = {"flash_series", "flash_events", "periodicity", "rotor_count"}


def _top_level(path: Path) -> tuple[set[str], set[str]]:
    """(classes, functions) defined at the top of a module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    classes = {n.name for n in tree.body if isinstance(n, ast.ClassDef)}
    functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    return classes, functions


def test_no_product_module_holds_a_per_return_flash_estimator():
    """No module of `signatures` defines a per-return flash series, periodicity or estimate, nor a
    per-return estimator function."""
    found = []
    for path in sorted(Path(signatures.__file__).parent.rglob("*.py")):
        classes, functions = _top_level(path)
        found += [f"{path.name}: {name}" for name in sorted((classes & PER_RETURN_TYPES)
                                                            | (functions & PER_RETURN_ESTIMATORS))]
    assert found == []


def test_the_reference_holds_the_per_return_forms():
    """The per-return forms are the tests' own reference, not imported from the product."""
    classes, functions = _top_level(REFERENCE)
    assert PER_RETURN_TYPES <= classes and PER_RETURN_ESTIMATORS <= functions
