"""A second, independent FMCW return model, for testing only (docs/signal-model.md, "Held-out model").

The classifiers are fitted to `signatures.simulate`; this package renders the same scenes
(`signatures.scene.Scene`, same presets, same file format, same SNR definition) with
different physics and shares no simulation code with it, so that a benchmark on its returns
measures how far the fitted models carry to a world they never saw. Nothing may be trained
or tuned on it. Airframes never trained on ship as `unseen_profiles()`.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from importlib import resources

import numpy as np

from signatures.errors import SignaturesError
from lab.heldout.airframe import AirframeTruth, uav_points
from lab.heldout.receiver import ReceiverTruth, clutter, receive, thermal_noise
from lab.heldout.synthesis import if_cube
from signatures.profiles import UavProfile, parse_profiles
from signatures.radar import C, Preset, RadarConfig
from signatures.recording import RadarSite, Recording
from signatures.scene import Scene

HELDOUT_VERSION = "1"
SITE = RadarSite(lat_deg=47.397, lon_deg=8.548, alt_m=430.0)
START = datetime(2026, 3, 1, 9, 30, 0, tzinfo=timezone.utc)

__all__ = ["HELDOUT_VERSION", "HeldoutTruth", "Parts", "render", "simulate", "unseen_profiles"]


@dataclass(frozen=True)
class HeldoutTruth:
    """What the held-out model put in the cube."""

    label: str
    range_m: float
    radial_speed_mps: float
    elevation_deg: float
    range_offset_m: float
    airframe: AirframeTruth | None
    receiver: ReceiverTruth

    @property
    def rotor_rate_hz(self) -> float:
        return float(np.mean(self.airframe.rotor_rates_hz)) if self.airframe else 0.0


@dataclass(frozen=True)
class Parts:
    """The cube's parts before the receiver (None when absent) and what the ADC delivers."""

    target: np.ndarray | None  # mean power 1 per IF sample
    clutter: np.ndarray | None
    noise: np.ndarray | None
    iq: np.ndarray  # complex64, receiver imperfections applied
    truth: HeldoutTruth


def unseen_profiles() -> dict[str, UavProfile]:
    """Airframes no classifier was trained or validated on (signatures/data/unseen_profiles.json)."""
    text = resources.files("signatures.data").joinpath("unseen_profiles.json").read_text()
    return parse_profiles(json.loads(text), "unseen profiles")


def _target(scene: Scene, config: RadarConfig, n_chirps: int, n_samples: int,
            rng: np.random.Generator) -> tuple[np.ndarray, AirframeTruth]:
    t = np.arange(n_chirps) * config.pri_s
    pts, truth = uav_points(scene, t, C / config.carrier_hz, rng)
    centre = scene.range_m + scene.radial_speed_mps * t
    s = ((2.0 * centre[:, None]).astype(np.float32) * pts.along_los + pts.norm_sq) \
        / (centre ** 2).astype(np.float32)[:, None]
    offsets = centre.astype(np.float32)[:, None] * s / (1.0 + np.sqrt(1.0 + s))  # |P + x| - |P|, stable
    speeds = scene.radial_speed_mps + (np.gradient(offsets, np.float32(config.pri_s), axis=0) if n_chirps > 1
                                       else np.zeros_like(offsets))
    cube = if_cube(centre, offsets, speeds, pts.amplitude, config, n_samples)
    cube *= np.float32(1.0 / math.sqrt(max(float(np.vdot(cube, cube).real) / cube.size, 1e-30)))
    return cube, truth


def render(scene: Scene, config: RadarConfig, n_chirps: int, n_samples: int, seed: int | None = None) -> Parts:
    """Target, clutter, noise and the received cube. Target, clutter, noise and receiver draw
    from their own streams of `seed`, so removing one leaves the others bit-identical."""
    if scene.kind == "bird":
        raise SignaturesError("the held-out model renders UAVs and empty scenes, not birds")
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4)]
    target, frame = None, None
    if scene.kind == "uav":
        target, frame = _target(scene, config, n_chirps, n_samples, streams[0])
    noise_power = 1.0 if scene.kind == "none" else (None if scene.snr_db is None else 10 ** (-scene.snr_db / 10))
    clut = None
    if scene.clutter_db is not None and noise_power is not None:
        clut = clutter(config, n_chirps, n_samples, noise_power * 10 ** (scene.clutter_db / 10), streams[1])
    noise = None if noise_power is None else thermal_noise(n_chirps, n_samples, noise_power, streams[2])
    air = target if clut is None else (clut if target is None else target + clut)
    iq, rx = receive(air, noise, (n_chirps, n_samples), streams[3])
    truth = HeldoutTruth(label=scene.label, range_m=scene.range_m if target is not None else 0.0,
                         radial_speed_mps=scene.radial_speed_mps, elevation_deg=scene.elevation_deg,
                         range_offset_m=config.range_offset_m, airframe=frame, receiver=rx)
    return Parts(target, clut, noise, iq, truth)


def gate_offset(preset: Preset, scene: Scene, seed: int | None) -> float:
    """Range-gate start with the target's mid-dwell range 30-70 % into the window (whole metres)."""
    frac = np.random.default_rng(np.random.SeedSequence(seed).spawn(5)[4]).uniform(0.3, 0.7)
    mid = scene.range_m + scene.radial_speed_mps * preset.dwell_s / 2
    return float(max(0.0, math.floor(mid - frac * preset.window_m)))


def simulate(scene: Scene, preset: Preset, seed: int | None = None, *, range_offset_m: float | None = None,
             site: RadarSite = SITE, start_time: datetime = START) -> tuple[Recording, HeldoutTruth]:
    """One dwell of `preset` on `scene` as a Recording (attribute `simulation` names this model)."""
    offset = gate_offset(preset, scene, seed) if range_offset_m is None else range_offset_m
    config = preset.with_offset(offset)
    parts = render(scene, config, preset.n_chirps, preset.n_samples, seed)
    doc = {"model": f"heldout/{HELDOUT_VERSION}", "preset": preset.name, "seed": seed,
           "scene": scene.model_dump(mode="json"), "truth": asdict(parts.truth)}
    rec = Recording(config=config, site=site, start_time=start_time, iq=parts.iq,
                    simulation=json.dumps(doc, sort_keys=True, separators=(",", ":")))
    return rec, parts.truth
