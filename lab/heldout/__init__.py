"""A second, independent FMCW return model, for testing only (docs/signal-model.md, "Held-out model").

The classifiers are fitted to `signatures.sim.simulate`; this package renders the same scenes
(`signatures.sim.scene.Scene`, same presets, same file format, same SNR definition) with
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

from dataclasses import replace

from signatures.dsp import rd
from signatures.errors import SignaturesError
from lab.heldout.airframe import AirframeTruth, uav_points
from lab.heldout.bird import BirdTruth, bird_points
from lab.heldout.receiver import ReceiverTruth, clutter, receive, thermal_noise
from lab.heldout.synthesis import if_cube
from signatures.profiles import UavProfile, parse_profiles
from signatures.radar import C, Preset, RadarConfig
from signatures.recording import RadarSite, Recording
from signatures.sim.scene import MultiScene, Scene

HELDOUT_VERSION = "2"
#: Chirps synthesised at a time: every shipped dwell (<= 8192) is one chunk, a long CW dwell several.
CHUNK = 8192
SITE = RadarSite(lat_deg=47.397, lon_deg=8.548, alt_m=430.0)
START = datetime(2026, 3, 1, 9, 30, 0, tzinfo=timezone.utc)

__all__ = ["HELDOUT_VERSION", "HeldoutTruth", "Parts", "render", "simulate", "simulate_many", "unseen_profiles"]


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
    bird: BirdTruth | None = None

    @property
    def rotor_rate_hz(self) -> float:
        """Mean mechanical rotor rate flown, rev/s."""
        return float(np.mean(self.airframe.rotor_rates_hz)) if self.airframe else 0.0

    @property
    def pattern_rate_hz(self) -> float:
        """Mean over rotors of the rate at which the flash pattern repeats (`AirframeTruth.pattern_rates_hz`)."""
        return float(np.mean(self.airframe.pattern_rates_hz)) if self.airframe else 0.0


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
            rng: np.random.Generator) -> tuple[np.ndarray, AirframeTruth | BirdTruth]:
    t = np.arange(n_chirps) * config.pri_s
    maker = uav_points if scene.kind == "uav" else bird_points
    pts, truth = maker(scene, t, C / config.carrier_hz, rng)
    centre = scene.range_m + scene.radial_speed_mps * t
    s = ((2.0 * centre[:, None]).astype(np.float32) * pts.along_los + pts.norm_sq) \
        / (centre ** 2).astype(np.float32)[:, None]
    offsets = centre.astype(np.float32)[:, None] * s / (1.0 + np.sqrt(1.0 + s))  # |P + x| - |P|, stable
    speeds = scene.radial_speed_mps + (np.gradient(offsets, np.float32(config.pri_s), axis=0) if n_chirps > 1
                                       else np.zeros_like(offsets))
    del s  # a 10 s CW dwell holds 50000 x ~120 points: synthesise it in chunks to keep the peak down
    cube = np.concatenate([if_cube(centre[a:a + CHUNK], offsets[a:a + CHUNK], speeds[a:a + CHUNK],
                                   pts.amplitude[a:a + CHUNK], config, n_samples)
                           for a in range(0, n_chirps, CHUNK)], axis=0)
    cube *= np.float32(1.0 / math.sqrt(max(float(np.vdot(cube, cube).real) / cube.size, 1e-30)))
    return cube, truth


def render(scene: Scene, config: RadarConfig, n_chirps: int, n_samples: int, seed: int | None = None) -> Parts:
    """Target, clutter, noise and the received cube. Target, clutter, noise and receiver draw
    from their own streams of `seed`, so removing one leaves the others bit-identical."""
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4)]
    target, frame = None, None
    if scene.kind != "none":
        target, frame = _target(scene, config, n_chirps, n_samples, streams[0])
    noise_power = 1.0 if scene.kind == "none" else (None if scene.snr_db is None else 10 ** (-scene.snr_db / 10))
    clut = None
    if scene.clutter_db is not None and noise_power is not None:
        clut = clutter(config, n_chirps, n_samples, noise_power * 10 ** (scene.clutter_db / 10), streams[1])
    elif scene.clutter_to_signal_db is not None:  # over the target's unit power
        clut = clutter(config, n_chirps, n_samples, 10 ** (scene.clutter_to_signal_db / 10), streams[1])
    noise = None if noise_power is None else thermal_noise(n_chirps, n_samples, noise_power, streams[2])
    air = target if clut is None else (clut if target is None else target + clut)
    iq, rx = receive(air, noise, (n_chirps, n_samples), streams[3])
    truth = HeldoutTruth(label=scene.label, range_m=scene.range_m if target is not None else 0.0,
                         radial_speed_mps=scene.radial_speed_mps, elevation_deg=scene.elevation_deg,
                         range_offset_m=config.range_offset_m,
                         airframe=frame if isinstance(frame, AirframeTruth) else None, receiver=rx,
                         bird=frame if isinstance(frame, BirdTruth) else None)
    return Parts(target, clut, noise, iq, truth)


def _truth_doc(truth: HeldoutTruth) -> dict:
    """The truth as JSON-ready data, with the mean rotor rate and each rotor's pattern rate."""
    doc = asdict(truth)
    if truth.airframe is not None:
        doc.update(rotor_rate_hz=truth.rotor_rate_hz, pattern_rates_hz=list(truth.airframe.pattern_rates_hz))
    return doc


def _in_domain(rec: Recording, domain: str) -> Recording:
    """The IF recording as a radar of `domain` delivers it (docs/format.md): a CW waveform has one
    sample per pulse at t = 0 of the sweep, which is the CW sample itself; a range radar delivers
    the range spectrum (periodic Hann, no fftshift, no clutter removal). Written here, not taken from
    the training side's converter, so that the held-out model shares none of its code."""
    if domain == "if":
        return rec
    if domain == "cw":
        return replace(rec, domain="cw")
    return replace(rec, iq=rd.range_fft(rec.iq, suppress_clutter=False), domain=domain)


def gate_offset(preset: Preset, scene: Scene, seed: int | None) -> float:
    """Range-gate start with the target's mid-dwell range 30-70 % into the window (whole metres)."""
    frac = np.random.default_rng(np.random.SeedSequence(seed).spawn(5)[4]).uniform(0.3, 0.7)
    mid = scene.range_m + scene.radial_speed_mps * preset.dwell_s / 2
    return float(max(0.0, math.floor(mid - frac * preset.window_m)))


def simulate(scene: Scene, preset: Preset, seed: int | None = None, *, range_offset_m: float | None = None,
             site: RadarSite = SITE, start_time: datetime = START) -> tuple[Recording, HeldoutTruth]:
    """One dwell of `preset` on `scene` as a Recording in the preset's domain (attribute
    `simulation` names this model)."""
    offset = gate_offset(preset, scene, seed) if range_offset_m is None else range_offset_m
    config = preset.with_offset(0.0 if preset.domain == "cw" else offset)
    parts = render(scene, config, preset.n_chirps, preset.n_samples, seed)
    doc = {"model": f"heldout/{HELDOUT_VERSION}", "preset": preset.name, "seed": seed,
           "scene": scene.model_dump(mode="json"), "truth": _truth_doc(parts.truth)}
    rec = Recording(config=config, site=site, start_time=start_time, iq=parts.iq,
                    simulation=json.dumps(doc, sort_keys=True, separators=(",", ":")))
    return _in_domain(rec, preset.domain), parts.truth


def simulate_many(multi: MultiScene, preset: Preset, seed: int | None = None, *, range_offset_m: float | None = None,
                  site: RadarSite = SITE, start_time: datetime = START) -> tuple[Recording, list[HeldoutTruth]]:
    """Several targets in one dwell of `preset` (`MultiScene`: noise of unit power, each target at its
    own `snr_db` over it), through one receiver; a truth per target, in order. The gate starts so
    that the targets' mid-dwell ranges sit 30-70 % into it; a target outside it is refused."""
    n = len(multi.targets)
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(n + 4)]
    cw = preset.domain == "cw"
    if range_offset_m is None:
        mids = [t.range_m + t.radial_speed_mps * preset.dwell_s / 2 for t in multi.targets]
        frac = streams[n + 3].uniform(0.3, 0.7)
        span = max(mids) - min(mids)
        range_offset_m = float(max(0.0, math.floor(min(mids) - frac * max(preset.window_m - span, 0.0))))
    config = preset.with_offset(0.0 if cw else range_offset_m)
    lo, hi = config.range_window_m
    air = None
    frames = []
    for i, target in enumerate(multi.targets):
        ends = (target.range_m, target.range_m + target.radial_speed_mps * preset.dwell_s)
        if not cw and not (lo <= min(ends) and max(ends) < hi):
            raise SignaturesError(f"targets[{i}]: range {target.range_m:g} m leaves the gate [{lo:g}, {hi:g}) m")
        cube, frame = _target(target, config, preset.n_chirps, preset.n_samples, streams[i])
        assert target.snr_db is not None
        cube *= np.float32(10 ** (target.snr_db / 20))
        air = cube if air is None else air + cube
        frames.append(frame)
    power = multi.clutter_power()
    if power is not None:
        air = air + clutter(config, preset.n_chirps, preset.n_samples, power, streams[n])
    noise = thermal_noise(preset.n_chirps, preset.n_samples, 1.0, streams[n + 1])
    iq, rx = receive(air, noise, (preset.n_chirps, preset.n_samples), streams[n + 2])
    truths = [HeldoutTruth(label=t.label, range_m=t.range_m, radial_speed_mps=t.radial_speed_mps,
                           elevation_deg=t.elevation_deg, range_offset_m=config.range_offset_m,
                           airframe=f if isinstance(f, AirframeTruth) else None, receiver=rx,
                           bird=f if isinstance(f, BirdTruth) else None) for t, f in zip(multi.targets, frames)]
    doc = {"model": f"heldout/{HELDOUT_VERSION}", "preset": preset.name, "seed": seed,
           "scene": multi.model_dump(mode="json"), "truths": [_truth_doc(t) for t in truths]}
    rec = Recording(config=config, site=site, start_time=start_time, iq=iq,
                    simulation=json.dumps(doc, sort_keys=True, separators=(",", ":")))
    return _in_domain(rec, preset.domain), truths
