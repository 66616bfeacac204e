"""What a simulated dwell contains: the target, its motion, clutter and noise.

A `Scene` is plain data (validated); `signatures.sim.simulate` turns it into IQ.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from signatures.profiles import UavProfile

SceneKind = Literal["uav", "bird", "none"]


class BirdParams(BaseModel):
    """Flapping-wing target: two line wings on a point body."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    wing_length_m: float = Field(default=0.35, gt=0.02, le=2.0)
    flap_rate_hz: float = Field(default=6.0, gt=0.2, le=40.0)
    flap_amplitude_deg: float = Field(default=40.0, gt=0, le=80)


class Nuisance(BaseModel):
    """What reality varies and a type label does not fix (docs/signal-model.md "Domain randomisation").

    Every default reproduces the plain simulator exactly, so a scene without a `Nuisance` and a
    scene with `Nuisance()` render the same cube. Training sets draw these at random so that the
    classifiers learn what survives them (`signatures.sim.sampling.NuisanceDistribution`).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    # --- the airframe as flown
    rotor_rate_scale: float = Field(default=1.0, ge=0.5, le=1.5,
                                    description="mean rotor rate / the profile's nominal (hover vs climb, payload)")
    blade_rcs_spread: float = Field(default=0.0, ge=0, le=1.0, description="std of per-blade amplitude factors")
    tip_weight: float = Field(default=0.0, ge=0, le=5.0,
                              description="an extra point scatterer at each blade tip, relative to the blade")
    body_scatterers: int = Field(default=0, ge=0, le=12, description="extra body points (arms, gear, payload)")
    radial_accel_mps2: float = Field(default=0.0, ge=-20, le=20)
    blade_cone_deg: float = Field(default=0.0, ge=0, le=10,
                                  description="blades coned up out of the rotor plane by their lift")
    # --- the radar
    phase_noise_rad: float = Field(default=0.0, ge=0, le=0.5, description="random-walk phase step per chirp")
    iq_gain_imbalance: float = Field(default=0.0, ge=0, le=0.3, description="relative Q-channel gain error")
    iq_phase_imbalance_deg: float = Field(default=0.0, ge=0, le=15)
    dc_offset: float = Field(default=0.0, ge=0, le=10, description="complex DC, in noise standard deviations")
    adc_bits: int | None = Field(default=None, ge=4, le=24, description="quantise I and Q (full scale = peak)")
    beam_taper_db: float = Field(default=0.0, ge=0, le=20,
                                 description="two-way antenna gain drop at the dwell's edges (scanning beam)")
    clutter_spread_mps: float = Field(default=0.0, ge=0, le=5, description="intrinsic motion of clutter (foliage)")


class Scene(BaseModel):
    """One target (or none) seen by the radar during one dwell.

    Powers: the target's mean power per IF sample is 1; white noise has power
    10**(-snr_db/10) (so `snr_db` is target power over noise power per IF sample,
    before any processing gain); clutter has power 10**(clutter_db/10) times the
    noise power (clutter-to-noise ratio). `snr_db=None` means noiseless.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: SceneKind = "uav"
    profile: UavProfile | None = None
    bird: BirdParams | None = None
    range_m: float = Field(default=100.0, gt=0, le=1e5, description="slant range at the first chirp")
    radial_speed_mps: float = Field(default=0.0, ge=-500, le=500, description="+ = receding")
    elevation_deg: float = Field(default=10.0, ge=-90, le=90)
    yaw_deg: float | None = Field(default=None, ge=-360, le=360, description="None = random")
    snr_db: float | None = Field(default=20.0, ge=-60, le=120)
    clutter_db: float | None = Field(default=None, ge=-30, le=80, description="clutter-to-noise ratio")
    blade_to_body_db: float | None = Field(
        default=None, ge=-40, le=20, description="blade/body power; None = -10 dB +- 3 dB random")
    attitude_wobble_deg: float = Field(default=1.0, ge=0, le=20)
    rotor_rate_jitter: float = Field(default=0.005, ge=0, le=0.1, description="std of per-rotor rate offset")
    nuisance: Nuisance | None = None
    # --- conditions of real radars the estimators must hold on (docs/signal-model.md "Test conditions").
    # Every default reproduces the plain simulator: a scene that sets none of them renders the same cube.
    rotor_rate_hz: float | None = Field(
        default=None, gt=1.0, le=500.0,
        description="common mechanical rotor rate flown, rev/s (None: the profile's); e.g. idle 63-71 Hz")
    blade_weights: tuple[tuple[float, ...], ...] | None = Field(
        default=None, description="field amplitude of every blade, rotors x blades_per_rotor (1 = untagged)")
    tagged_blades: int = Field(default=0, ge=0, le=128,
                               description="blades carrying a reflective tag, chosen by the seed")
    tag_gain_db: float = Field(default=10.0, ge=0.0, le=40.0, description="power gain of a tagged blade")
    tag_layout: Literal["random", "spread"] = Field(
        default="random", description="random: any blades; spread: one per rotor before a second on any rotor")
    tag_pattern: str | None = Field(
        default=None, pattern=r"^[01]+$", max_length=128,
        description="which blades carry a tag (at tag_gain_db), one digit per blade, rotor by rotor: "
                    "10101010 tags blade 0 of each of a quad's 4 rotors, 11000000 both blades of rotor 0")
    clutter_to_signal_db: float | None = Field(
        default=None, ge=-30, le=80, description="clutter power over the target's (instead of clutter_db)")

    @model_validator(mode="after")
    def _consistent(self) -> "Scene":
        if self.kind == "uav" and self.profile is None:
            raise ValueError("a 'uav' scene needs a profile")
        if self.kind != "uav" and self.profile is not None:
            raise ValueError(f"a {self.kind!r} scene has no UAV profile")
        if self.kind != "bird" and self.bird is not None:
            raise ValueError("bird parameters given for a scene that is not a bird")
        if self.clutter_db is not None and self.snr_db is None and self.kind != "none":
            raise ValueError("clutter_db is relative to noise: give snr_db too")
        if self.clutter_to_signal_db is not None:
            if self.clutter_db is not None:
                raise ValueError("give clutter_db (over noise) or clutter_to_signal_db (over the target), not both")
            if self.kind == "none":
                raise ValueError("clutter_to_signal_db needs a target: use clutter_db for an empty scene")
        blades = (self.profile.rotors * self.profile.blades_per_rotor) if self.profile is not None else 0
        if self.kind != "uav" and (self.rotor_rate_hz is not None or self.blade_weights is not None
                                   or self.tagged_blades or self.tag_pattern is not None):
            raise ValueError("rotor_rate_hz, blade_weights, tagged_blades and tag_pattern describe a UAV's rotors")
        if self.tag_pattern is not None:
            if self.tagged_blades or self.blade_weights is not None:
                raise ValueError("give one of tag_pattern, tagged_blades and blade_weights")
            if len(self.tag_pattern) != blades or "1" not in self.tag_pattern:
                raise ValueError(f"tag_pattern must be {blades} digits (the airframe's blades, rotor by rotor) "
                                 "with at least one 1")
        if self.blade_weights is not None:
            p = self.profile
            assert p is not None
            if self.tagged_blades:
                raise ValueError("give blade_weights or tagged_blades, not both")
            if len(self.blade_weights) != p.rotors or any(len(r) != p.blades_per_rotor for r in self.blade_weights):
                raise ValueError(f"blade_weights must be {p.rotors} rotors x {p.blades_per_rotor} blades "
                                 f"(profile {p.slug!r})")
            flat = [w for r in self.blade_weights for w in r]
            if not all(math.isfinite(w) and 0.0 <= w <= 100.0 for w in flat):
                raise ValueError("blade_weights must be finite amplitudes in [0, 100]")
            if not any(w > 0 for w in flat):
                raise ValueError("blade_weights: at least one blade must reflect")
        if self.tagged_blades > blades:
            raise ValueError(f"tagged_blades ({self.tagged_blades}) exceeds the airframe's {blades} blades")
        return self

    @property
    def label(self) -> str:
        """Class label: the profile slug, 'bird' or 'none'."""
        return self.profile.slug if self.profile is not None else self.kind

    @property
    def hovering(self) -> bool:
        return abs(self.radial_speed_mps) < 0.5


class MultiScene(BaseModel):
    """Several targets in one dwell (two drones and a bird, say), each with its own truth.

    Powers: the noise has power 1 per IF sample; target i has mean power 10**(snr_db_i/10) (its own
    `snr_db`, so each keeps the single-scene meaning); clutter has power 10**(clutter_db/10)
    (clutter-to-noise) or 10**(clutter_to_signal_db/10) times the first target's power. The
    targets' own clutter settings must be unset: the ground is shared.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    targets: tuple[Scene, ...] = Field(min_length=1, max_length=8)
    clutter_db: float | None = Field(default=None, ge=-30, le=80, description="clutter-to-noise ratio")
    clutter_to_signal_db: float | None = Field(default=None, ge=-30, le=80,
                                               description="clutter over the first target's power")

    @model_validator(mode="after")
    def _consistent(self) -> "MultiScene":
        for i, t in enumerate(self.targets):
            if t.kind == "none":
                raise ValueError(f"targets[{i}]: an empty scene is not a target")
            if t.snr_db is None:
                raise ValueError(f"targets[{i}]: snr_db sets the target's power over the common noise")
            if t.clutter_db is not None or t.clutter_to_signal_db is not None:
                raise ValueError(f"targets[{i}]: clutter is the scene's, not a target's")
        if self.clutter_db is not None and self.clutter_to_signal_db is not None:
            raise ValueError("give clutter_db (over noise) or clutter_to_signal_db (over the target), not both")
        return self

    def clutter_power(self) -> float | None:
        """The shared clutter's power over the unit noise, or None without clutter."""
        if self.clutter_db is not None:
            return 10 ** (self.clutter_db / 10)
        if self.clutter_to_signal_db is not None:
            first = self.targets[0].snr_db
            assert first is not None  # validated
            return 10 ** ((self.clutter_to_signal_db + first) / 10)
        return None
