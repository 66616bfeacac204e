"""Body velocity under strong ground clutter: a moving body is not mistaken for a hovering
one when the clutter in its range bin outweighs it, and a hovering body is still found."""

from __future__ import annotations

import numpy as np
import pytest

from signatures.features import extract
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_velocity_within_one_bin_in_heavy_clutter(preset: str) -> None:
    rng = np.random.default_rng(32)
    pre = get_preset(preset)
    profiles = list(shipped_profiles().values())
    wrong = []
    for i in range(16):
        v = 0.0 if i % 2 else float(rng.choice([-1, 1]) * rng.uniform(1.0, 15.0))
        scene = Scene(profile=profiles[i % 3], range_m=float(rng.uniform(60, 1100)), radial_speed_mps=v,
                      elevation_deg=float(rng.uniform(0, 40)), snr_db=float(rng.uniform(0, 30)),
                      clutter_db=float(rng.uniform(12, 22)))
        rec, _ = simulate(scene, pre, int(rng.integers(1 << 30)))
        err = abs(extract(rec).radial_velocity_mps - rec.config.fold_velocity(v, rec.n_samples))
        if err > rec.config.doppler_bin_mps(rec.n_chirps) * 1.01:
            wrong.append((v, err))
    assert wrong == []
