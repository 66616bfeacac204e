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

Conditions (`CONDITIONS`, `evaluate_condition`): scene families of a real radar the estimators
must hold on (an S-band CW radar, a hovering quadcopter with tagged blades, strong
static clutter, idling rotors, 0.82 s and 10 s dwells), scored on what that radar needs:
|v| < 1 m/s, the mechanical rotor rate within 3 %, rotors seen within +-1.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from signatures.features import extract
from signatures.profiles import UavProfile, shipped_profiles
from signatures.radar import Preset, get_preset
from signatures.recording import Recording
from signatures.sim.scene import Scene
from signatures.classify.verify import ROTOR_BAND

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
    from signatures.sim.simulate import simulate

    if world == "randomised":
        from signatures.sim.sampling import randomised

        scene = randomised(scene, np.random.default_rng(seed))
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


# --- conditions of a real radar: an S-band CW radar and a hovering, tagged quadcopter ---

#: A DJI-class quadcopter (Phantom / Mavic size: 9.4-inch propellers, 0.35 m diagonal wheelbase),
#: nominal rotor rate mid-way in the 143-179 Hz of flight. Not a shipped profile: no classifier
#: knows it; the conditions score estimators, not the classifiers.
DJI_QUAD = UavProfile(slug="dji-quad", name="DJI-class quadcopter", rotors=4, arms=4, blades_per_rotor=2,
                      blade_length_m=0.12, rotor_rate_hz=161.0, propeller_distance_m=0.35)
#: The real radar's carriers.
SBAND_CARRIERS_HZ = (3.30e9, 3.35e9, 3.40e9)
#: Scoring of the conditions: |v| below this, rotor rate within this share, rotors seen within this.
HOVER_SPEED_MPS = 1.0
CONDITION_RATE_TOLERANCE = 0.03
ROTORS_SEEN_TOLERANCE = 1.0


@dataclass(frozen=True)
class Condition:
    """A family of scenes drawn per seed: the radar (a preset, its dwell in pulses, carriers drawn
    from `carriers_hz`), the airframe, and uniform ranges (inclusive for the integers) of what varies."""

    name: str
    description: str
    preset: str = "cw-sband"
    n_pulses: int = 4096
    carriers_hz: tuple[float, ...] = SBAND_CARRIERS_HZ
    profile: UavProfile = DJI_QUAD
    rotor_rate_hz: tuple[float, float] = (143.0, 179.0)
    tagged_blades: tuple[int, int] = (1, 8)
    tag_gain_db: tuple[float, float] = (6.0, 15.0)
    clutter_to_signal_db: tuple[float, float] | None = (20.0, 40.0)  # None: the simulator's own clutter
    snr_db: tuple[float, float] = (0.0, 10.0)
    range_m: tuple[float, float] = (100.0, 1000.0)
    #: std of each rotor's rate about the common one (`Scene.rotor_rate_jitter`), drawn per scene
    rotor_rate_jitter: tuple[float, float] = (0.005, 0.005)
    #: radial speed (m/s), drawn per scene with a random sign where it varies (0: hovering)
    speed_mps: tuple[float, float] = (0.0, 0.0)
    #: tag patterns (`Scene.tag_pattern`), one drawn per scene instead of `tagged_blades`; () draws none
    tag_patterns: tuple[str, ...] = ()
    #: blade length (m), drawn per scene where given (the airframe's own otherwise)
    blade_length_m: tuple[float, float] | None = None
    #: the radar's pulse rate (Hz) where it is not the preset's
    prf_hz: float | None = None

    def scene(self, rng: np.random.Generator) -> tuple[Scene, Preset]:
        """One scene of the condition and the radar that sees it (its carrier drawn)."""
        pre = get_preset(self.preset).with_pulses(self.n_pulses)
        carrier = float(self.carriers_hz[int(rng.integers(len(self.carriers_hz)))])
        pre = replace(pre, config=pre.config.replace(carrier_hz=carrier))
        if self.prf_hz is not None:  # a CW channel: one sample a pulse, ramp = PRI
            pri = 1.0 / self.prf_hz
            pre = replace(pre, config=pre.config.replace(pri_s=pri, ramp_s=pri, bandwidth_hz=self.prf_hz,
                                                         sample_rate_hz=self.prf_hz))
        scene = Scene(profile=self.profile, range_m=float(rng.uniform(*self.range_m)), radial_speed_mps=0.0,
                      snr_db=float(rng.uniform(*self.snr_db)), rotor_rate_hz=float(rng.uniform(*self.rotor_rate_hz)),
                      tagged_blades=int(rng.integers(self.tagged_blades[0], self.tagged_blades[1] + 1)),
                      tag_gain_db=float(rng.uniform(*self.tag_gain_db)),
                      clutter_to_signal_db=None if self.clutter_to_signal_db is None else
                      float(rng.uniform(*self.clutter_to_signal_db)))
        lo, hi = self.rotor_rate_jitter
        if hi > lo:  # drawn only where it varies: the other conditions' scenes stay as they were
            scene = scene.model_copy(update={"rotor_rate_jitter": float(rng.uniform(lo, hi))})
        elif lo != Scene.model_fields["rotor_rate_jitter"].default:
            scene = scene.model_copy(update={"rotor_rate_jitter": lo})
        if self.speed_mps[1] > 0:  # drawn last and only here: the hovering conditions' scenes stay as they were
            speed = float(rng.uniform(*self.speed_mps)) * (1.0 if rng.random() < 0.5 else -1.0)
            scene = scene.model_copy(update={"radial_speed_mps": speed})
        if self.tag_patterns or self.blade_length_m is not None:  # drawn after the rest, only here
            scene = self._airframe(scene, rng)
        return scene, pre

    def _airframe(self, scene: Scene, rng: np.random.Generator) -> Scene:
        """`scene` with its tag pattern and blade length drawn (`tag_patterns`, `blade_length_m`);
        validated anew (a model copy is not)."""
        doc = dict(scene.model_dump(), profile=scene.profile)
        if self.tag_patterns:
            doc.update(tagged_blades=0, tag_pattern=self.tag_patterns[int(rng.integers(len(self.tag_patterns)))])
        if self.blade_length_m is not None:
            doc["profile"] = replace(self.profile, blade_length_m=float(rng.uniform(*self.blade_length_m)))
        return Scene(**doc)

    def draw(self, seed: int) -> tuple[Scene, Preset, int]:
        """Seeded scene `seed` of the condition: the scene, its radar and the simulator's seed (the
        same in every world and for every tool that renders the condition's scenes)."""
        rng = np.random.default_rng([seed, 31])
        scene, pre = self.scene(rng)
        return scene, pre, int(rng.integers(2**31))


#: Tag patterns of a quad's 8 blades, rotor by rotor (`Scene.tag_pattern`): one blade; one per rotor;
#: both of one rotor; all alike.
TAG_PATTERNS = ("10000000", "10101010", "11000000", "11111111")
_TAGGED = "hovering DJI-class quad, 1-8 of its 8 blades tagged (+6..+15 dB), clutter +20..+40 dB over it"
_PHANTOM4 = shipped_profiles()["phantom4"]
_PAPER = dict(preset="paper", n_pulses=600, carriers_hz=(77e9,), profile=_PHANTOM4, tagged_blades=(0, 0),
              clutter_to_signal_db=None, rotor_rate_hz=(0.9 * _PHANTOM4.rotor_rate_hz, 1.1 * _PHANTOM4.rotor_rate_hz))
CONDITIONS: dict[str, Condition] = {c.name: c for c in (
    Condition("cw-hover-tagged", f"CW 3.3-3.4 GHz, PRI 200 us, 0.82 s (4096 pulses); {_TAGGED}; rotors 143-179 Hz"),
    Condition("cw-hover-tagged-10s", "as cw-hover-tagged over 10 s (50000 pulses)", n_pulses=50000),
    Condition("cw-idle-tagged", "as cw-hover-tagged, rotors idling at 63-71 Hz", rotor_rate_hz=(63.0, 71.0)),
    Condition("cw-idle-tagged-10s", "as cw-idle-tagged over 10 s (50000 pulses)", rotor_rate_hz=(63.0, 71.0),
              n_pulses=50000),
    Condition("cw-hover-equal", "as cw-hover-tagged without tags (equal blades): the control",
              tagged_blades=(0, 0)),
    Condition("cw-moving-tagged", "as cw-hover-tagged, flying 2-12 m/s towards or away from the radar "
              "(the clutter's line then lies off the body's)", speed_mps=(2.0, 12.0)),
    *(Condition(f"cw-{state}-{pattern}", f"CW 3.3-3.4 GHz at 5000.1 Hz, 0.82 s; hovering quad with blades of 5-12 cm, "
                f"rotors {state} at {lo:g}-{hi:g} Hz (tips alias beyond ~110 m/s), blades {pattern} tagged "
                f"(+6..+15 dB, rotor by rotor), clutter +20..+40 dB", rotor_rate_hz=(lo, hi), tag_patterns=(pattern,),
                blade_length_m=(0.05, 0.12), prf_hz=5000.1)
      for state, lo, hi in (("idle", 60.0, 75.0), ("on", 120.0, 180.0)) for pattern in TAG_PATTERNS),
    Condition("paper-hover", "paper (77 GHz, 26 ms); hovering Phantom 4 at 0.9-1.1x its rate, equal blades, "
              "rotors 0.5 % apart (std): the control", **_PAPER),
    Condition("paper-hover-spread", "as paper-hover, each rotor's rate 2-4 % (std) off the common one, as a "
              "real quad's are (max - min: 2.5-11 %, median 6.5 %)", rotor_rate_jitter=(0.02, 0.04), **_PAPER),
)}


@dataclass(frozen=True)
class Estimate:
    """What an estimator says about one return (the scored quantities)."""

    detected: bool
    rotor_rate_hz: float
    radial_velocity_mps: float
    rotors_seen: float
    #: the rate rests on a flash train the verification reads (`verify.min_flash_score`); None: not said
    train: bool | None = None


def feature_estimate(rec: Recording) -> Estimate:
    """Today's estimators, as `authn check` runs them (`signatures.features.extract`)."""
    from signatures.features import extract

    result = extract(rec)
    f = result.features
    from signatures.classify.verify import min_flash_score

    unknown = result.physics.get("rotors_unknown", 0.0) >= 0.5  # the count said it cannot tell
    return Estimate(bool(f.detected > 0), float(f.rotor_rate_hz), float(f.radial_velocity_mps),
                    math.nan if unknown else float(result.physics.get("rotors_seen", 0.0)),
                    bool(f.flash_score >= min_flash_score(result.physics)))


@dataclass(frozen=True)
class Truth:
    """What is independently known of one dwell (None: not known, so not scored)."""

    rotor_rate_hz: float | None = None  # mean mechanical rotor rate
    radial_velocity_mps: float | None = None  # the body's
    rotors: int | None = None


@dataclass(frozen=True)
class Scores:
    """Shares of n dwells, each over the dwells whose truth holds that quantity (None: none did)."""

    n: int
    detected: float
    velocity_ok: float | None  # |v - truth| < HOVER_SPEED_MPS
    rotor_ok: float | None  # rotor rate within CONDITION_RATE_TOLERANCE of the truth
    rotors_ok: float | None  # rotors seen within ROTORS_SEEN_TOLERANCE of the rotor count
    rotor_median_err: float | None  # median |relative rotor-rate error|
    at_double: float | None  # rotor rate within tolerance of 2x the truth (the blade-flash rate read as the rotor's)
    at_half: float | None  # within tolerance of 0.5x the truth (one blade's flash a turn taken for two blades')
    rotor_ok_5: float | None = None  # rotor rate within RATE_TOLERANCE (5 %) of the truth
    at_triple: float | None = None  # within tolerance of 3x the truth
    rotors_over: float | None = None  # rotors seen over the rotor count + ROTORS_SEEN_TOLERANCE (a wrong bound)
    rotors_unknown: float | None = None  # rotors seen not known (NaN: the count said it cannot tell)
    train: float | None = None  # share whose rate rests on a flash train the verification reads
    rotor_ok_5_train: float | None = None  # rotor rate within 5 %, over those dwells


def score(pairs: list[tuple[Estimate, Truth]]) -> Scores:
    """The real-radar scores of estimates against their truths: one rule for simulated conditions
    (`evaluate_condition`) and a site's own recordings (`lab.recordings`)."""
    if not pairs:
        raise ValueError("no dwells to score")

    def share(xs: list[bool]) -> float | None:
        return sum(xs) / len(xs) if xs else None

    def near(e: Estimate, t: Truth, factor: float, tolerance: float = CONDITION_RATE_TOLERANCE) -> bool:
        want = factor * (t.rotor_rate_hz or 0.0)
        return abs(e.rotor_rate_hz - want) <= tolerance * want

    rated = [(e, t) for e, t in pairs if t.rotor_rate_hz is not None]
    errs = [abs(e.rotor_rate_hz - t.rotor_rate_hz) / t.rotor_rate_hz for e, t in rated if t.rotor_rate_hz]
    return Scores(
        len(pairs), sum(e.detected for e, _ in pairs) / len(pairs),
        share([abs(e.radial_velocity_mps - t.radial_velocity_mps) < HOVER_SPEED_MPS
               for e, t in pairs if t.radial_velocity_mps is not None]),
        share([near(e, t, 1.0) for e, t in rated]),
        share([abs(e.rotors_seen - t.rotors) <= ROTORS_SEEN_TOLERANCE for e, t in pairs if t.rotors is not None]),
        float(np.median(errs)) if errs else None,
        share([near(e, t, 2.0) for e, t in rated]), share([near(e, t, 0.5) for e, t in rated]),
        share([near(e, t, 1.0, RATE_TOLERANCE) for e, t in rated]), share([near(e, t, 3.0) for e, t in rated]),
        share([e.rotors_seen > t.rotors + ROTORS_SEEN_TOLERANCE for e, t in pairs if t.rotors is not None]),
        share([math.isnan(e.rotors_seen) for e, t in pairs if t.rotors is not None]),
        share([bool(e.train) for e, _ in pairs if e.train is not None]),
        share([near(e, t, 1.0, RATE_TOLERANCE) for e, t in rated if e.train]))


@dataclass(frozen=True)
class ConditionRow:
    """Scores of one condition in one world. Rates are shares of the n returns."""

    condition: str
    world: str
    n: int
    detected: float
    velocity_ok: float  # |v - truth| < HOVER_SPEED_MPS
    rotor_ok: float  # rotor rate within CONDITION_RATE_TOLERANCE of the mean mechanical rate flown
    rotors_ok: float  # rotors seen within ROTORS_SEEN_TOLERANCE of the rotor count
    rotor_median_err: float  # median |relative rotor-rate error|
    at_double: float  # rotor rate within tolerance of 2x the truth (the blade-flash rate read as the rotor's)
    at_half: float  # within tolerance of 0.5x the truth
    seconds: float  # wall time of the row (render and estimate)
    rotor_ok_5: float = 0.0  # rotor rate within RATE_TOLERANCE (5 %)
    at_triple: float = 0.0  # rotor rate within tolerance of 3x the truth
    rotors_over: float = 0.0  # rotors seen over the rotor count + ROTORS_SEEN_TOLERANCE
    rotors_unknown: float = 0.0  # rotors seen not known (NaN)
    train: float = 0.0  # share whose rate rests on a flash train the verification reads
    rotor_ok_5_train: float = 0.0  # rotor rate within 5 % over those dwells (0 where none)

    def as_dict(self) -> dict[str, float | int | str]:
        return dict(self.__dict__)


def render_condition(condition: Condition, world: str, seed: int) -> tuple[Recording, Scene, float, float, int]:
    """(recording, scene, mean mechanical rotor rate flown, radial speed, rotors) of one seeded scene
    of `condition` in `world`."""
    if world not in WORLDS:
        raise ValueError(f"world {world!r} is not one of {', '.join(WORLDS)}")
    scene, pre, sim_seed = condition.draw(seed)
    rec, rate, _, speed = render_in_world(world, scene, pre, sim_seed)
    return rec, scene, rate, speed, condition.profile.rotors


def evaluate_condition(condition: str | Condition, n: int = 40, seed: int = 0, world: str = "training",
                       estimate: Callable[[Recording], Estimate] = feature_estimate) -> ConditionRow:
    """Score `estimate` on n seeded returns of a condition (a name of `CONDITIONS` or a `Condition`)
    in one world: the same scenes every run and in every world. Pass another `estimate` to score
    an estimator before it is wired into the features."""
    import time

    cond = CONDITIONS[condition] if isinstance(condition, str) else condition
    t0 = time.perf_counter()
    pairs = []
    for i in range(n):
        rec, _, rate, speed, rotors = render_condition(cond, world, seed * 100_003 + i)
        pairs.append((estimate(rec), Truth(rate, speed, rotors)))
    s = score(pairs)  # every truth is known here: no share is None
    return ConditionRow(cond.name, world, n, s.detected, *(float(v) for v in (
        s.velocity_ok, s.rotor_ok, s.rotors_ok, s.rotor_median_err, s.at_double, s.at_half)), time.perf_counter() - t0,
        *(float(v or 0.0) for v in (s.rotor_ok_5, s.at_triple, s.rotors_over, s.rotors_unknown, s.train,
                                    s.rotor_ok_5_train)))
