"""The scene sampler: one function that draws a random scene, for training sets and benchmarks.

What a random scene is: a target (a UAV profile, a bird or nothing), where it is (range and
elevation), how it moves (hovering, or a radial speed of either sign), how loud it is (SNR)
and whether ground clutter surrounds it. `sample_scene` draws one from a `SceneDistribution`;
the training sets (`signatures.train.dataset`) and the benchmarks (`lab.bench`) each own their
distribution and call this one sampler.

Why a module of its own, beside `signatures.sim.scene` rather than inside `signatures.train.dataset`:
the dataset module is the training-set machinery (grid geometry, splits, worker processes,
the cache); the benchmarks need the sampler but none of that, and the sampler needs nothing
from it. Keeping it here also keeps the dependency one way: `authn` uses `signatures`, never
the reverse.

Reproducibility. A scene is a pure function of the generator's state and the distribution.
The *order* of the draws is part of the distribution (`SceneDistribution.order`), and so are
two historical details (sign-then-magnitude for a continuous speed, magnitude-then-sign for a
discrete one; clutter decided by where a uniform draw falls, `clutter_band`). The shipped
models were trained and validated on scenes drawn with the dataset's order, and the published
benchmark figures with the benchmarks' orders: changing an order, or a band's position,
redraws every scene for the same seed. Add a distribution instead of "tidying" one (and bump
`signatures.train.dataset.GENERATOR_VERSION` if the dataset's draws change).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from numbers import Real
from typing import Literal

import numpy as np

from signatures.profiles import UavProfile
from signatures.sim.scene import BirdParams, Nuisance, Scene

Span = tuple[float, float]
#: Draws (range_m, elevation_deg) from the generator: geometry other than independent uniforms
#: (the dataset's 3-D grid points of one split).
Position = Callable[[np.random.Generator], tuple[float, float]]
Target = UavProfile | Literal["bird", "none"]

#: The steps `SceneDistribution.order` may name.
STEPS = ("position", "range", "elevation", "speed", "snr", "clutter")


@dataclass(frozen=True)
class SceneDistribution:
    """What `sample_scene` draws from (spans are uniform [low, high)).

    order: the draw steps, in the order they are drawn: "range" and "elevation" (uniform over
        their spans) or "position" (both at once, from the `position` callable given to
        `sample_scene`), and "speed", "snr", "clutter" (a step left out gives 0 m/s, a noiseless
        scene, no clutter). Part of the distribution: see the module.
    hover_fraction: probability that the target hovers (radial speed 0).
    birds_hover: False: birds always move (and draw nothing for hovering).
    speed_mps: the moving speed's magnitude, uniform over the span; sign drawn first.
    speeds_mps: if set, the magnitude is one of these instead; drawn before the sign.
    snr_db: a span, or one fixed value (no draw).
    clutter_band: clutter iff a uniform draw u in [0, 1) falls in [low, high): its probability
        is high - low; where the band sits only matters to reproduce earlier draws.
    clutter_db: the clutter level when there is clutter.
    bird_*: the bird's wing length, flap rate and (if a span) flap amplitude; None leaves the
        `BirdParams` default and draws nothing.
    none_clutter_db: if set, an empty ("none") scene is only clutter at this level, at the
        scene's default geometry (the draws of its other steps are made and discarded).
    nuisance: if set, every UAV and bird scene also gets a random `Nuisance` (domain
        randomisation), drawn after everything else.
    """

    order: tuple[str, ...]
    range_m: Span | None = None
    elevation_deg: Span | None = None
    hover_fraction: float = 0.0
    birds_hover: bool = True
    speed_mps: Span | None = None
    speeds_mps: tuple[float, ...] | None = None
    snr_db: Span | float | None = None
    clutter_band: Span = (0.0, 0.0)
    clutter_db: Span = (0.0, 0.0)
    bird_wing_m: Span = (0.15, 0.5)
    bird_flap_hz: Span = (3.0, 10.0)
    bird_flap_amplitude_deg: Span | None = None
    none_clutter_db: Span | None = None
    nuisance: NuisanceDistribution | None = None

    def __post_init__(self) -> None:
        unknown = set(self.order) - set(STEPS)
        if unknown:
            raise ValueError(f"unknown sampling steps {sorted(unknown)} (known: {', '.join(STEPS)})")
        steps = set(self.order)
        if len(steps) != len(self.order):
            raise ValueError(f"a step appears twice in {self.order}")
        spans = steps & {"range", "elevation"}
        if ("position" in steps) == bool(spans) or len(spans) == 1:
            raise ValueError("order needs either 'position' or both 'range' and 'elevation'")
        if spans and (self.range_m is None or self.elevation_deg is None):
            raise ValueError("'range' and 'elevation' steps need range_m and elevation_deg spans")
        if self.speed_mps is None and self.speeds_mps is None:
            raise ValueError("a distribution needs speed_mps or speeds_mps")


@dataclass(frozen=True)
class NuisanceDistribution:
    """Domain randomisation: spans (uniform [low, high)) of what reality varies, drawn per scene.

    The defaults are the training distribution (docs/signal-model.md "Domain randomisation"):
    rotor rates +-15 % (hover against climb and payload), per-rotor spread up to 3 %, unequal
    and coned blades, tip scatterers, extra body points, radial acceleration, oscillator phase noise,
    IQ imbalance, DC offset, ADC resolution, a scanning beam and moving clutter.
    """

    rotor_rate_scale: Span = (0.85, 1.15)
    rotor_rate_jitter: Span = (0.005, 0.03)
    attitude_wobble_deg: Span = (0.5, 5.0)
    blade_to_body_db: Span = (-18.0, -4.0)
    blade_rcs_spread: Span = (0.0, 0.3)
    tip_weight: Span = (0.0, 0.1)
    body_scatterers: tuple[int, int] = (0, 6)
    radial_accel_mps2: Span = (-3.0, 3.0)
    phase_noise_rad: Span = (0.0, 0.02)
    iq_gain_imbalance: Span = (0.0, 0.05)
    iq_phase_imbalance_deg: Span = (0.0, 3.0)
    dc_offset: Span = (0.0, 1.0)
    adc_bits: tuple[int | None, ...] = (None, 10, 12, 14)
    beam_taper_db: Span = (0.0, 3.0)
    clutter_spread_mps: Span = (0.0, 0.5)
    blade_cone_deg: Span = (0.0, 4.0)


def sample_nuisance(rng: np.random.Generator, dist: NuisanceDistribution) -> tuple[Nuisance, dict[str, float]]:
    """One draw of `dist`: the `Nuisance` and the scene fields it also sets (wobble, jitter,
    blade-to-body ratio)."""
    u = lambda span: float(rng.uniform(*span))  # noqa: E731
    drawn = dict(rotor_rate_scale=u(dist.rotor_rate_scale), blade_rcs_spread=u(dist.blade_rcs_spread),
                 tip_weight=u(dist.tip_weight),
                 body_scatterers=int(rng.integers(dist.body_scatterers[0], dist.body_scatterers[1] + 1)),
                 radial_accel_mps2=u(dist.radial_accel_mps2), phase_noise_rad=u(dist.phase_noise_rad),
                 iq_gain_imbalance=u(dist.iq_gain_imbalance), iq_phase_imbalance_deg=u(dist.iq_phase_imbalance_deg),
                 dc_offset=u(dist.dc_offset), adc_bits=dist.adc_bits[int(rng.integers(len(dist.adc_bits)))],
                 beam_taper_db=u(dist.beam_taper_db), clutter_spread_mps=u(dist.clutter_spread_mps))
    scene_fields = dict(rotor_rate_jitter=u(dist.rotor_rate_jitter), attitude_wobble_deg=u(dist.attitude_wobble_deg),
                        blade_to_body_db=u(dist.blade_to_body_db))
    # drawn last, so that a seed's earlier draws do not depend on whether the cone is drawn
    nz = Nuisance(**drawn, blade_cone_deg=u(dist.blade_cone_deg))
    return nz, scene_fields


def randomised(scene: Scene, rng: np.random.Generator, dist: NuisanceDistribution | None = None) -> Scene:
    """`scene` with one draw of `dist` (default: `NuisanceDistribution()`) applied: what the
    randomised world renders of a scene drawn without nuisances."""
    nuisance, fields = sample_nuisance(rng, dist or NuisanceDistribution())
    return scene.model_copy(update={"nuisance": nuisance, **fields})


def sample_scene(rng: np.random.Generator, target: Target, dist: SceneDistribution,
                 position: Position | None = None) -> Scene:
    """One random scene of `target` drawn from `dist` with `rng` (advances `rng`).

    `position` draws (range_m, elevation_deg) when `dist.order` has a "position" step. The
    simulator seed, an azimuth and the like are the caller's, drawn after this returns.
    """
    kind = target if isinstance(target, str) else "uav"
    if kind not in ("uav", "bird", "none"):
        raise ValueError(f"unknown target {target!r} (a UavProfile, 'bird' or 'none')")
    got: dict[str, object] = {}
    for step in dist.order:
        if step == "position":
            if position is None:
                raise ValueError("this distribution draws a position: pass `position`")
            got["range"], got["elevation"] = position(rng)
        elif step == "range":
            got["range"] = float(rng.uniform(*dist.range_m))
        elif step == "elevation":
            got["elevation"] = float(rng.uniform(*dist.elevation_deg))
        elif step == "speed":
            got["speed"] = _speed(rng, dist, kind)
        elif step == "snr":
            got["snr"] = _snr(rng, dist.snr_db)
        elif step == "clutter":
            u = rng.random()
            low, high = dist.clutter_band
            got["clutter"] = float(rng.uniform(*dist.clutter_db)) if low <= u < high else None
    common = dict(range_m=got["range"], elevation_deg=got["elevation"], snr_db=got.get("snr"),
                  clutter_db=got.get("clutter"))
    if kind == "none":
        if dist.none_clutter_db is not None:
            return Scene(kind="none", clutter_db=float(rng.uniform(*dist.none_clutter_db)))
        return Scene(kind="none", **common)
    speed = got.get("speed", 0.0)
    if kind == "bird":
        params = dict(wing_length_m=float(rng.uniform(*dist.bird_wing_m)),
                      flap_rate_hz=float(rng.uniform(*dist.bird_flap_hz)))
        if dist.bird_flap_amplitude_deg is not None:
            params["flap_amplitude_deg"] = float(rng.uniform(*dist.bird_flap_amplitude_deg))
        return Scene(kind="bird", bird=BirdParams(**params), radial_speed_mps=speed, **common,
                     **_randomised(rng, dist, bird=True))
    return Scene(kind="uav", profile=target, radial_speed_mps=speed, **common, **_randomised(rng, dist))


def _randomised(rng: np.random.Generator, dist: SceneDistribution, bird: bool = False) -> dict[str, object]:
    """The scene fields domain randomisation sets (none without `dist.nuisance`)."""
    if dist.nuisance is None:
        return {}
    nz, fields = sample_nuisance(rng, dist.nuisance)
    if bird:  # a bird has no rotors and its own wing-to-body ratio
        fields = {"attitude_wobble_deg": fields["attitude_wobble_deg"]}
    return {"nuisance": nz, **fields}


def _snr(rng: np.random.Generator, snr_db: Span | float | None) -> float | None:
    """A fixed SNR (or None: noiseless) draws nothing; a span draws uniformly."""
    if snr_db is None or isinstance(snr_db, Real):
        return None if snr_db is None else float(snr_db)
    return float(rng.uniform(*snr_db))


def _speed(rng: np.random.Generator, dist: SceneDistribution, kind: str) -> float:
    """0 when hovering, else a signed speed (see `SceneDistribution` for the order of draws)."""
    if (kind != "bird" or dist.birds_hover) and rng.random() < dist.hover_fraction:
        return 0.0
    if dist.speeds_mps is not None:
        return float(rng.choice(dist.speeds_mps)) * float(rng.choice((-1.0, 1.0)))
    return float(rng.choice([-1, 1]) * rng.uniform(*dist.speed_mps))
