"""cedarpy imported without its policy-tree module until something reads that module.

cedarpy's package imports `cedarpy.pst`, its typed mirror of Cedar's policy syntax tree (31
frozen dataclasses, ~13 ms of a cold check: more than any other import of one check but numpy,
typer and h5py), which only `cedarpy.policies_to_pst` uses; deciding (validation, the policy
JSON, `is_authorized`) never does. `defer`, called before the first `import cedarpy`,
registers a stand-in for `cedarpy.pst` that imports the real module the first time any name
it lacks is read (a class, `__all__`, `__path__`), and from then on `sys.modules` and
`cedarpy.pst` hold the real module. Nothing is decided differently: the engine is the same.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys
import threading
import types
from typing import Any

__all__ = ["NAME", "defer", "deferred"]

NAME = "cedarpy.pst"
_lock = threading.Lock()


class _Deferred(types.ModuleType):
    """`cedarpy.pst` until a name it lacks is read: then the real module, imported."""

    def __getattr__(self, name: str) -> Any:  # only for names the stand-in does not have
        return getattr(_imported(self), name)


def _imported(stand_in: _Deferred) -> types.ModuleType:
    """The real `cedarpy.pst`, imported once (a failure leaves the stand-in to try again)."""
    with _lock:
        module = sys.modules.get(NAME)
        if module is not stand_in and module is not None:
            return module
        spec = stand_in.__spec__
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[NAME] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            sys.modules[NAME] = stand_in
            raise
        parent = sys.modules.get("cedarpy")
        if parent is not None:
            parent.pst = module  # type: ignore[attr-defined]
        return module


def defer() -> None:
    """Register the stand-in, unless cedarpy is imported already (or is not installed: its
    import then fails as it would have)."""
    if "cedarpy" in sys.modules or NAME in sys.modules:
        return
    package = importlib.util.find_spec("cedarpy")
    if package is None or package.submodule_search_locations is None:
        return
    spec = importlib.machinery.PathFinder.find_spec(NAME, list(package.submodule_search_locations))
    if spec is None or spec.loader is None:
        return
    stand_in = _Deferred(NAME)
    stand_in.__spec__, stand_in.__loader__, stand_in.__package__ = spec, spec.loader, "cedarpy"
    stand_in.__file__ = spec.origin
    sys.modules[NAME] = stand_in


def deferred() -> bool:
    """`cedarpy.pst` is still the stand-in (nothing has read it)."""
    return isinstance(sys.modules.get(NAME), _Deferred)
