"""Estimator accuracy on simulated returns over a grid of SNR, in any world (docs/features.md).

Scenes: the three shipped UAV profiles in turn, range uniform in 100-1100 m,
half hovering and half moving with a radial speed uniform in +-15 m/s, random
yaw, blade-to-body ratio and rotor phases (the simulator's defaults). SNR as in
the simulator: target over noise power per IF sample, before processing gain.
Worlds: `training` (the simulator the classifiers were fitted to), `randomised` (the same
with a domain-randomisation draw per scene, `sampling.NuisanceDistribution`) and `heldout`
(the independent signal model, `lab.heldout`: measured, never tuned on).
Truth: flash rate = the profile's flashes per turn x the mean rotor rate flown; rotor count;
range at the first chirp; radial velocity (at mid-dwell where the target accelerates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from signatures.features import extract
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.scene import Scene
from signatures.verify import ROTOR_BAND

RATE_TOLERANCE = 0.05
WORLDS = ("training", "randomised", "heldout")


@dataclass(frozen=True)
class Row:
    preset: str
    snr_db: float
    n: int
    detected: float  # share of returns detected
    flash_ok: float  # share with flash rate within 5 %
    rotor_ok: float  # share with rotor rate within 5 %
    range_ok: float  # share with range within one range bin
    velocity_ok: float  # share with radial velocity within one Doppler bin
    flash_median_err: float  # median relative flash-rate error
    rotors_ok: float = 0.0  # share with rotors seen / rotors within verify.ROTOR_BAND
    rotors_median: float = 0.0  # median of rotors seen / rotors (where counted)
    world: str = "training"

    def as_dict(self) -> dict[str, float | int | str]:
        return dict(self.__dict__)


def scene_for(i: int, snr_db: float, rng: np.random.Generator) -> Scene:
    profiles = list(shipped_profiles().values())
    moving = i % 2 == 1
    return Scene(profile=profiles[i % len(profiles)], range_m=float(rng.uniform(100, 1100)),
                 radial_speed_mps=float(rng.uniform(-15, 15)) if moving else 0.0, snr_db=snr_db)


def render_in_world(world: str, scene: Scene, preset, seed: int):
    """(recording, mean rotor rate flown, range at the first chirp, radial speed) of `scene` in
    `world` (one of WORLDS)."""
    if world not in WORLDS:
        raise ValueError(f"world {world!r} is not one of {', '.join(WORLDS)}")
    if world == "heldout":
        from lab import heldout

        rec, truth = heldout.simulate(scene, preset, seed)
        return rec, truth.rotor_rate_hz, truth.range_m, truth.radial_speed_mps
    from signatures.simulate import simulate

    if world == "randomised":
        from signatures.sampling import NuisanceDistribution, sample_nuisance

        nuisance, fields = sample_nuisance(np.random.default_rng(seed), NuisanceDistribution())
        scene = scene.model_copy(update={"nuisance": nuisance, **fields})
    rec, truth = simulate(scene, preset, seed=seed)
    accel = scene.nuisance.radial_accel_mps2 if scene.nuisance else 0.0  # the Doppler line: mid-dwell speed
    return rec, truth.rotor_rate_hz, truth.range_m, truth.radial_speed_mps + accel * preset.dwell_s / 2.0


def evaluate(preset_name: str, snr_db: float, n: int, seed: int = 0, world: str = "training") -> Row:
    """Accuracy of the estimators on n simulated UAV returns at one SNR in one world (the same
    scenes and seeds in every world)."""
    preset = get_preset(preset_name)
    rng = np.random.default_rng([seed, int(round(snr_db * 10)) + 1000])
    det = flash = rotor = rng_ok = vel = rotors_ok = 0
    errs, rotors = [], []
    for i in range(n):
        scene = scene_for(i, snr_db, rng)
        rec, rate, range_m, speed = render_in_world(world, scene, preset, int(rng.integers(2**31)))
        profile = scene.profile
        assert profile is not None
        result = extract(rec)
        f = result.features
        det += f.detected > 0
        true_flash = profile.blade_flash_rate_hz / profile.rotor_rate_hz * rate
        err = abs(f.flash_rate_hz - true_flash) / true_flash
        errs.append(err)
        flash += err <= RATE_TOLERANCE
        rotor += abs(f.rotor_rate_hz - rate) <= RATE_TOLERANCE * rate
        rng_ok += abs(f.range_m - range_m) <= rec.config.range_bin_m(rec.n_samples)
        v_true = rec.config.fold_velocity(speed)
        vel += abs(f.radial_velocity_mps - v_true) <= rec.config.doppler_bin_mps(rec.n_chirps)
        seen = result.physics.get("rotors_seen", 0.0) / profile.rotors
        rotors_ok += ROTOR_BAND[0] <= seen <= ROTOR_BAND[1]
        if seen > 0:
            rotors.append(seen)
    return Row(preset_name, snr_db, n, det / n, flash / n, rotor / n, rng_ok / n, vel / n,
               float(np.median(errs)), rotors_ok / n, float(np.median(rotors)) if rotors else 0.0, world)
