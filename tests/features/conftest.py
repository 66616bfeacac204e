"""Simulated returns shared by the feature tests (simulated once per session)."""

from __future__ import annotations

import pytest

from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate


def sim(kind: str = "uav", model: str | None = "m300", preset: str = "paper", seed: int = 1, **kw):
    profile = shipped_profiles()[model] if kind == "uav" else None
    scene = Scene(kind=kind, profile=profile, **{"range_m": 400.0, "snr_db": 10.0, **kw})
    return simulate(scene, get_preset(preset), seed=seed)


@pytest.fixture(scope="session")
def returns():
    """A few typical returns: moving and hovering UAVs, a bird, an empty scene with clutter."""
    return {
        "m300_moving": sim(radial_speed_mps=6.0)[0],
        "m600_hover": sim(model="m600", radial_speed_mps=0.0, seed=2)[0],
        "bird": sim(kind="bird", model=None, radial_speed_mps=4.0, seed=3)[0],
        "none": sim(kind="none", model=None, clutter_db=20.0, seed=4)[0],
    }
