"""Simulation time per return for both presets (`python -m pytest benchmarks --benchmark-enable`)."""

from __future__ import annotations

import pytest

from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate

SCENES = {
    "m600-moving-clutter": dict(profile="m600", radial_speed_mps=6.0, clutter_db=15.0),
    "phantom4-hover": dict(profile="phantom4", radial_speed_mps=0.0, clutter_db=None),
    "bird": dict(profile=None, radial_speed_mps=4.0, clutter_db=15.0),
    "none": dict(profile=None, radial_speed_mps=0.0, clutter_db=15.0),
}


@pytest.mark.parametrize("preset", ["paper", "wide"])
@pytest.mark.parametrize("name", sorted(SCENES))
def test_simulate(benchmark, preset: str, name: str) -> None:
    spec = dict(SCENES[name])
    slug = spec.pop("profile")
    kind = "uav" if slug else name
    scene = Scene(kind=kind, profile=shipped_profiles()[slug] if slug else None, range_m=400.0, snr_db=10.0,
                  **spec)
    pre = get_preset(preset)
    rec, _ = benchmark(simulate, scene, pre, 1)
    assert rec.iq.shape == (pre.n_chirps, pre.n_samples)
