"""Synthesise the dechirped IF cube of a scene (the signal convention of docs/format.md).

Model (V.C. Chen's rotating-blade line integral). Every scatterer i has a
slow-time complex amplitude a_i[n] that carries its carrier phase
4*pi*R_i(t_n)/lambda, and a fast-time beat exp(j*2*pi*2*S*(R_i - R_off)/c*t_k).
A blade of length L on a hub at range R_h, at angle theta(t) in its rotor plane,
integrates to

    integral_0^L exp(j*4*pi/lambda*(R_h + r*c(t))) dr
        = L * exp(j*4*pi*R_h/lambda) * exp(j*Phi/2) * sinc(Phi/(2*pi)),
    Phi = 4*pi*L*c(t)/lambda,

with c(t) the projection of the blade's unit vector on the line of sight. The
blade is shorter than a range bin, so its fast-time beat is taken at the hub.
The cube is then E * (A @ G): A = (n_chirps x scatterers) slow-time amplitudes,
G = (scatterers x n_samples) static fast-time offsets of each scatterer from the
body, E = the body's fast-time beat over the dwell (rank one when hovering).
No Python loop runs over chirps or samples.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from datetime import datetime, timezone

import numpy as np

from signatures.sim.domain import as_recorded
from signatures.errors import SignaturesError
from signatures.profiles import UavProfile
from signatures.radar import C, Preset, RadarConfig
from signatures.recording import RadarSite, Recording
from signatures.sim.scene import BirdParams, MultiScene, Nuisance, Scene

SIMULATOR_VERSION = "2"  # bump when simulate() draws or computes different returns (cached datasets key on it)
DEFAULT_SITE = RadarSite(lat_deg=52.0, lon_deg=4.4, alt_m=2.0)
DEFAULT_START = datetime(2026, 1, 1, 12, 0, 0, tzinfo=timezone.utc)
HUB_TO_BODY_DB = -12.0  # each motor hub, relative to the fuselage point
#: Scatterer amplitudes are re-evaluated this often within a ramp (a blade tip at 115 m/s
#: turns its carrier phase by 0.15 cycle in 2.5 us at 77 GHz; a flash lasts ~18 us).
SUBSTEP_S = 2.5e-6


@dataclass(frozen=True)
class Truth:
    """What the simulator put in the cube (for tests, datasets and plots)."""

    label: str
    range_m: float
    radial_speed_mps: float
    elevation_deg: float
    rotor_rates_hz: tuple[float, ...] = ()
    blades_per_rotor: int = 0
    blade_length_m: float = 0.0
    flap_rate_hz: float = 0.0
    range_offset_m: float = 0.0
    #: field amplitude of every blade (rotors x blades), () when all blades are alike (weight 1)
    blade_weights: tuple[tuple[float, ...], ...] = ()
    rotors: int = 0

    @property
    def rotor_rate_hz(self) -> float:
        """Mean mechanical rotor rate, rev/s: the truth a rotor-rate estimate is scored against."""
        return float(np.mean(self.rotor_rates_hz)) if self.rotor_rates_hz else 0.0

    @property
    def blade_flash_rate_hz(self) -> float:
        """Flashes per second of one rotor (N*f for even N blades, 2*N*f for odd), tags or not."""
        n = self.blades_per_rotor
        return (n if n % 2 == 0 else 2 * n) * self.rotor_rate_hz if n else 0.0

    @property
    def pattern_rates_hz(self) -> tuple[float, ...]:
        """Per rotor, the rate at which its flash pattern repeats: its mechanical rate when its
        blades reflect unequally (a tagged blade marks each turn), else its flash rate."""
        n = self.blades_per_rotor
        per_turn = n if n % 2 == 0 else 2 * n
        out = []
        for i, f in enumerate(self.rotor_rates_hz):
            w = self.blade_weights[i] if self.blade_weights else ()
            out.append(f if w and max(w) - min(w) > 1e-9 else per_turn * f)
        return tuple(out)

    @property
    def pattern_rate_hz(self) -> float:
        """Mean of `pattern_rates_hz`: the flash rate the blade pattern implies."""
        return float(np.mean(self.pattern_rates_hz)) if self.rotor_rates_hz else 0.0

    @property
    def tip_speed_mps(self) -> float:
        return 2.0 * math.pi * self.rotor_rate_hz * self.blade_length_m


@dataclass(frozen=True)
class Components:
    """The cube split into its parts (each None when the scene has none)."""

    target: np.ndarray | None
    clutter: np.ndarray | None
    noise: np.ndarray | None
    truth: Truth
    #: receiver impairments applied to the sum (None: an ideal receiver) and their seed
    receiver: Nuisance | None = None
    receiver_seed: int = 0
    noise_power: float = 0.0

    def total(self, dtype: np.dtype | type = np.complex64) -> np.ndarray:
        parts = [p for p in (self.target, self.clutter, self.noise) if p is not None]
        out = parts[0].astype(dtype, copy=True)
        for p in parts[1:]:
            out += p
        if self.receiver is not None:
            out = _impair(out, self.receiver, self.noise_power, np.random.default_rng(self.receiver_seed))
        return out


def _impair(cube: np.ndarray, nz: Nuisance, noise_power: float, rng: np.random.Generator) -> np.ndarray:
    """What a real receiver adds: IQ gain/phase imbalance, a DC offset, ADC quantisation."""
    out = cube.copy()
    if nz.iq_gain_imbalance or nz.iq_phase_imbalance_deg:
        phi = math.radians(nz.iq_phase_imbalance_deg)
        q = (1.0 + nz.iq_gain_imbalance) * (math.cos(phi) * cube.imag - math.sin(phi) * cube.real)
        out.imag = q.astype(out.real.dtype)
    if nz.dc_offset:
        sigma = math.sqrt(noise_power) if noise_power > 0 else float(np.std(np.abs(out)))
        out += (nz.dc_offset * sigma * np.exp(1j * rng.uniform(0, 2 * math.pi))).astype(out.dtype)
    if nz.adc_bits is not None:
        full = 1.05 * float(max(np.max(np.abs(out.real)), np.max(np.abs(out.imag)), 1e-30))
        step = 2.0 * full / 2 ** nz.adc_bits
        out.real = np.round(out.real / step) * step
        out.imag = np.round(out.imag / step) * step
    return out


def _rotation(yaw: float, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """Body-to-world rotation Rz(yaw) Ry(pitch) Rx(roll), shape (n, 3, 3)."""
    cy, sy = math.cos(yaw), math.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    r = np.empty(pitch.shape + (3, 3))
    r[:, 0, 0] = cy * cp
    r[:, 0, 1] = cy * sp * sr - sy * cr
    r[:, 0, 2] = cy * sp * cr + sy * sr
    r[:, 1, 0] = sy * cp
    r[:, 1, 1] = sy * sp * sr + cy * cr
    r[:, 1, 2] = sy * sp * cr - cy * sr
    r[:, 2, 0] = -sp
    r[:, 2, 1] = cp * sr
    r[:, 2, 2] = cp * cr
    return r


def _line_integral(hub_proj: np.ndarray, dir_proj: np.ndarray, length: float,
                   wavelength: float) -> np.ndarray:
    """Chen's blade integral for hubs at LOS offsets hub_proj, blades along dir_proj (float64)."""
    k = 4.0 * math.pi / wavelength
    phi = k * length * dir_proj
    # carrier phase of the hub, wrapped before it meets the blade term
    phase = np.mod(k * hub_proj + 0.5 * phi, 2.0 * math.pi)
    return length * np.sinc(phi / (2.0 * math.pi)) * np.exp(1j * phase)


def _los_in_body(scene: Scene, t: np.ndarray, yaw: float, rng: np.random.Generator) -> np.ndarray:
    """Line-of-sight unit vector expressed in the body frame at each chirp, (n, 3)."""
    el = math.radians(scene.elevation_deg)
    los = np.array([math.cos(el), 0.0, math.sin(el)])  # radar -> target, world frame
    # forward tilt when moving (about 1 deg per m/s, at most 15 deg), plus slow wobble
    tilt = math.radians(min(15.0, abs(scene.radial_speed_mps)) * (1 if scene.radial_speed_mps >= 0 else -1))
    wob = math.radians(scene.attitude_wobble_deg)
    f_wob = rng.uniform(0.5, 2.0, size=2)
    ph = rng.uniform(0, 2 * math.pi, size=2)
    pitch = tilt + wob * np.sin(2 * math.pi * f_wob[0] * t + ph[0])
    roll = wob * np.sin(2 * math.pi * f_wob[1] * t + ph[1])
    rot = _rotation(yaw, pitch, roll)
    return np.einsum("nji,j->ni", rot, los)  # R^T los


def _uav_amplitudes(scene: Scene, t: np.ndarray, wavelength: float,
                    rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, Truth]:
    """Slow-time amplitudes (n, 1 + rotors) and static LOS offsets (1 + rotors,)."""
    p = scene.profile
    assert p is not None
    yaw = math.radians(scene.yaw_deg) if scene.yaw_deg is not None else rng.uniform(0, 2 * math.pi)
    w = _los_in_body(scene, t, yaw, rng)  # (n, 3)
    # rotor hubs: arms evenly spaced at radius D/2; coaxial pairs stacked +-5 cm
    per_arm = p.rotors // p.arms if p.rotors >= p.arms else 1
    arm_angle = 2 * math.pi * (np.arange(p.rotors) // per_arm) / p.arms
    z = np.where(np.arange(p.rotors) % per_arm == 1, -0.05, 0.05) if per_arm > 1 else np.full(p.rotors, 0.05)
    hubs = np.stack([0.5 * p.propeller_distance_m * np.cos(arm_angle),
                     0.5 * p.propeller_distance_m * np.sin(arm_angle), z], axis=1)  # (r, 3)
    hub_proj = w @ hubs.T  # (n, r) LOS offset of each hub
    nz = scene.nuisance
    # rotors: alternating spin, independent phases, small rate jitter
    jitter = np.clip(rng.normal(0, scene.rotor_rate_jitter, p.rotors), -3 * scene.rotor_rate_jitter,
                     3 * scene.rotor_rate_jitter)
    nominal = scene.rotor_rate_hz if scene.rotor_rate_hz is not None else p.rotor_rate_hz
    rates = nominal * (nz.rotor_rate_scale if nz else 1.0) * (1.0 + jitter)
    spin = np.where(np.arange(p.rotors) % 2 == 0, 1.0, -1.0)
    phase0 = rng.uniform(0, 2 * math.pi, p.rotors)
    blade_off = 2 * math.pi * np.arange(p.blades_per_rotor) / p.blades_per_rotor
    theta = (phase0[None, :, None] + spin[None, :, None] * 2 * math.pi * rates[None, :, None] * t[:, None, None]
             + blade_off[None, None, :])  # (n, r, b)
    dir_proj = w[:, None, None, 0] * np.cos(theta) + w[:, None, None, 1] * np.sin(theta)
    cone = math.radians(nz.blade_cone_deg) if nz is not None else 0.0
    if cone:  # blades coned up by their lift: seen off the rotor plane, a rotor's two blades flash apart
        dir_proj = math.cos(cone) * dir_proj + math.sin(cone) * w[:, None, None, 2]
    per_blade = _line_integral(hub_proj[:, :, None], dir_proj, p.blade_length_m, wavelength)  # (n, r, b)
    k = 4.0 * math.pi / wavelength
    hub_pts = np.exp(1j * np.mod(k * hub_proj, 2 * math.pi))  # motor hubs as points
    body = np.ones((t.size, 1), dtype=np.complex128)  # fuselage at the body centre
    # power bookkeeping: blades relative to body (fuselage + hubs)
    ratio_db = scene.blade_to_body_db if scene.blade_to_body_db is not None else rng.uniform(-13.0, -7.0)
    if nz is not None:  # drawn last: a scene without nuisance draws exactly what it always drew
        per_blade, body = _nuisance_scatterers(nz, p, per_blade, hub_proj, dir_proj, w, k, rng)
    blades = per_blade.sum(axis=2)
    hub_amp = 10 ** (HUB_TO_BODY_DB / 20)
    body_part = np.concatenate([body.sum(axis=1, keepdims=True), hub_amp * hub_pts], axis=1)
    p_body = float(np.mean(np.abs(body_part.sum(axis=1)) ** 2))
    p_blades = float(np.mean(np.abs(blades.sum(axis=1)) ** 2))
    blade_gain = math.sqrt(p_body / max(p_blades, 1e-300) * 10 ** (ratio_db / 10))
    weights = blade_weights(scene, rng)  # drawn last: an untagged scene draws what it always drew
    if weights is not None:  # a tag adds RCS: untagged blades keep the power ratio, tagged ones exceed it
        blades = (per_blade * weights[None, :, :]).sum(axis=2)
    amps = np.concatenate([body.sum(axis=1, keepdims=True), hub_amp * hub_pts + blade_gain * blades], axis=1)
    offsets = np.concatenate([[0.0], hub_proj.mean(axis=0)])
    truth = Truth(label=p.slug, range_m=scene.range_m, radial_speed_mps=scene.radial_speed_mps,
                  elevation_deg=scene.elevation_deg, rotor_rates_hz=tuple(float(r) for r in rates),
                  blades_per_rotor=p.blades_per_rotor, blade_length_m=p.blade_length_m, rotors=p.rotors,
                  blade_weights=() if weights is None else tuple(tuple(float(x) for x in r) for r in weights))
    return amps, offsets, truth


def blade_weights(scene: Scene, rng: np.random.Generator) -> np.ndarray | None:
    """Field amplitude of every blade (rotors, blades) of a UAV scene, None when all are alike.

    `scene.blade_weights` as given; else the blades `tag_pattern` names (rotor by rotor, drawing
    nothing) or `tagged_blades` blades get amplitude 10**(tag_gain_db/20) and the rest 1. Layout
    `random` picks the tagged blades uniformly (drawing from `rng` only when there are tags);
    `spread` tags blade 0 of rotors 0, 1, ... in turn, then blade 1, so that up to one tag per
    rotor every rotor carries one."""
    p = scene.profile
    assert p is not None
    if scene.blade_weights is not None:
        return np.asarray(scene.blade_weights, dtype=np.float64)
    total = p.rotors * p.blades_per_rotor
    if scene.tag_pattern is not None:  # the blades named, drawing nothing
        w = np.where(np.array([c == "1" for c in scene.tag_pattern]), 10 ** (scene.tag_gain_db / 20), 1.0)
        return w.reshape(p.rotors, p.blades_per_rotor)
    if not scene.tagged_blades:
        return None
    if scene.tag_layout == "random":
        chosen = rng.choice(total, size=scene.tagged_blades, replace=False)
    else:  # blade-major order: (rotor 0, blade 0), (rotor 1, blade 0), ...
        order = (np.arange(total) % p.rotors) * p.blades_per_rotor + np.arange(total) // p.rotors
        chosen = order[:scene.tagged_blades]
    w = np.ones(total)
    w[chosen] = 10 ** (scene.tag_gain_db / 20)
    return w.reshape(p.rotors, p.blades_per_rotor)


def _nuisance_scatterers(nz: Nuisance, p: UavProfile, per_blade: np.ndarray, hub_proj: np.ndarray,
                         dir_proj: np.ndarray, w: np.ndarray, k: float, rng: np.random.Generator
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Unequal blades, blade-tip scatterers and extra body points (arms, gear, payload).

    Returns the per-blade amplitudes (n, r, b) and the body's points (n, 1 + m), the fuselage
    first. The body points sit within the propeller circle and move with the attitude."""
    r, b = per_blade.shape[1:]
    if nz.blade_rcs_spread:
        per_blade = per_blade * np.clip(1.0 + nz.blade_rcs_spread * rng.standard_normal((r, b)), 0.1, None)
    if nz.tip_weight:
        tip = hub_proj[:, :, None] + p.blade_length_m * dir_proj
        per_blade = per_blade + nz.tip_weight * p.blade_length_m * np.exp(1j * np.mod(k * tip, 2 * math.pi))
    body = np.ones((w.shape[0], 1), dtype=np.complex128)
    if nz.body_scatterers:
        m = nz.body_scatterers
        radius = 0.5 * p.propeller_distance_m * np.sqrt(rng.uniform(0, 1, m))
        angle = rng.uniform(0, 2 * math.pi, m)
        pts = np.stack([radius * np.cos(angle), radius * np.sin(angle), rng.uniform(-0.15, 0.05, m)], axis=1)
        amp = rng.rayleigh(0.35, m) * np.exp(1j * rng.uniform(0, 2 * math.pi, m))
        body = np.concatenate([body, amp[None, :] * np.exp(1j * np.mod(k * (w @ pts.T), 2 * math.pi))], axis=1)
    return per_blade, body


def _bird_amplitudes(scene: Scene, t: np.ndarray, wavelength: float,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, Truth]:
    """A body plus two flapping line wings; wings about as strong as the body."""
    b = scene.bird or BirdParams()
    yaw = math.radians(scene.yaw_deg) if scene.yaw_deg is not None else rng.uniform(0, 2 * math.pi)
    w = _los_in_body(scene, t, yaw, rng)
    flap = math.radians(b.flap_amplitude_deg) * np.sin(2 * math.pi * b.flap_rate_hz * t
                                                       + rng.uniform(0, 2 * math.pi))
    bob = 0.1 * b.wing_length_m * np.cos(2 * math.pi * b.flap_rate_hz * t)  # body heave
    k = 4.0 * math.pi / wavelength
    body = np.exp(1j * np.mod(k * w[:, 2] * bob, 2 * math.pi))[:, None]
    wings = []
    for side in (1.0, -1.0):
        shoulder = w[:, 1] * side * 0.05 + w[:, 2] * bob
        direction = w[:, 1] * side * np.cos(flap) + w[:, 2] * np.sin(flap)
        wings.append(_line_integral(shoulder, direction, b.wing_length_m, wavelength))
    wing_sig = wings[0] + wings[1]
    ratio_db = scene.blade_to_body_db if scene.blade_to_body_db is not None else rng.uniform(-6.0, 0.0)
    gain = math.sqrt(np.mean(np.abs(body) ** 2) / max(np.mean(np.abs(wing_sig) ** 2), 1e-300)
                     * 10 ** (ratio_db / 10))
    amps = np.concatenate([body, gain * wing_sig[:, None]], axis=1)
    truth = Truth(label="bird", range_m=scene.range_m, radial_speed_mps=scene.radial_speed_mps,
                  elevation_deg=scene.elevation_deg, flap_rate_hz=b.flap_rate_hz)
    return amps, np.zeros(2), truth


def substeps(config: RadarConfig, n_samples: int) -> int:
    """Sub-steps per chirp at which scatterer amplitudes are evaluated: one per SUBSTEP_S of
    the ramp, at most one per fast-time sample."""
    return int(min(n_samples, max(1, math.ceil(config.ramp_s / SUBSTEP_S - 1e-9))))


def _cos_sin(phase: np.ndarray) -> np.ndarray:
    """exp(j*phase) for float32 phases, via cos/sin (much cheaper than complex exp)."""
    out = np.empty(phase.shape, dtype=np.complex64)
    out.real = np.cos(phase)
    out.imag = np.sin(phase)
    return out


def _target_cube(scene: Scene, config: RadarConfig, n_chirps: int, n_samples: int,
                 rng: np.random.Generator) -> tuple[np.ndarray | None, Truth]:
    t = np.arange(n_chirps) * config.pri_s
    lam = config.wavelength_m
    if scene.kind == "none":
        return None, Truth(label="none", range_m=0.0, radial_speed_mps=0.0, elevation_deg=0.0)
    maker = _uav_amplitudes if scene.kind == "uav" else _bird_amplitudes
    steps = substeps(config, n_samples)
    first = (np.arange(steps) * n_samples) // steps  # each sub-step's first fast-time sample
    t_sub = (t[:, None] + first[None, :] / config.sample_rate_hz).ravel()
    amps, offsets, truth = maker(scene, t_sub, lam, rng)  # (n_chirps * steps, m)
    amps = amps.reshape(n_chirps, steps, -1)
    nz = scene.nuisance
    accel = nz.radial_accel_mps2 if nz else 0.0
    # bulk translation: carrier phase in float64, wrapped, then everything in complex64
    bulk = np.mod(4.0 * math.pi / lam * (scene.range_m + scene.radial_speed_mps * t + 0.5 * accel * t * t),
                  2 * math.pi)
    if nz is not None and nz.phase_noise_rad:  # oscillator phase wander over the dwell
        bulk = bulk + np.cumsum(rng.normal(0.0, nz.phase_noise_rad, t.size))
    amps = amps * np.exp(1j * bulk)[:, None, None]
    if nz is not None and nz.beam_taper_db:  # a scanning beam: two-way gain falls off to the edges
        u = (t - t.mean()) / max(float(t.mean()), 1e-12)
        amps = amps * (10.0 ** (-nz.beam_taper_db * u * u / 20.0))[:, None, None]
    amps = amps.astype(np.complex64)
    kappa = 2.0 * math.pi * 2.0 * config.slope_hz_per_s / C  # beat phase per metre per second
    tk = (np.arange(n_samples) / config.sample_rate_hz).astype(np.float32)
    g = _cos_sin(np.float32(kappa) * offsets.astype(np.float32)[:, None] * tk[None, :])  # (m, k)
    hovering = scene.radial_speed_mps == 0.0 and accel == 0.0
    if hovering:
        g = g * _cos_sin(np.float32(kappa * (scene.range_m - config.range_offset_m)) * tk)[None, :]
    cube = np.empty((n_chirps, n_samples), dtype=np.complex64)
    for s, (a, b) in enumerate(zip(first, [*first[1:], n_samples])):
        cube[:, a:b] = amps[:, s, :] @ g[:, a:b]
    if not hovering:
        rel = (scene.range_m - config.range_offset_m + scene.radial_speed_mps * t
               + 0.5 * accel * t * t).astype(np.float32)
        cube *= _cos_sin(np.float32(kappa) * rel[:, None] * tk[None, :])
    power = float(np.vdot(cube, cube).real) / cube.size
    cube *= np.float32(1.0 / math.sqrt(max(power, 1e-30)))  # target power per IF sample = 1
    return cube, truth


def _clutter_cube(config: RadarConfig, n_chirps: int, n_samples: int, power: float,
                  rng: np.random.Generator, spread_mps: float = 0.0) -> np.ndarray:
    """Ground clutter: a scatterer in every range bin plus a few strong discretes; with
    `spread_mps` the diffuse part also moves (foliage: a Gaussian Doppler spectrum of that std)."""
    lo, hi = config.range_window_m
    bins = config.range_bin_m(n_samples)
    ranges = lo + (np.arange(n_samples) + rng.uniform(-0.5, 0.5, n_samples)) * bins
    amps = (rng.standard_normal(n_samples) + 1j * rng.standard_normal(n_samples)) * 0.3
    n_disc = int(rng.integers(2, 6))
    ranges = np.concatenate([ranges, rng.uniform(lo, hi, n_disc)])
    amps = np.concatenate([amps, rng.exponential(1.0, n_disc) ** 0.5 * 3.0
                           * np.exp(1j * rng.uniform(0, 2 * math.pi, n_disc))])
    kappa = 2.0 * math.pi * 2.0 * config.slope_hz_per_s / C
    tk = np.arange(n_samples) / config.sample_rate_hz
    profile = (amps[None, :] @ np.exp(1j * kappa * np.outer(ranges - lo, tk))).ravel()
    profile *= math.sqrt(power / max(float(np.mean(np.abs(profile) ** 2)), 1e-300))
    static = np.broadcast_to(profile.astype(np.complex64), (n_chirps, n_samples)).copy()
    if not spread_mps:
        return static
    # half the diffuse power moves: each bin's amplitude is Gaussian-filtered noise in slow time
    sigma_hz = 2.0 * spread_mps / config.wavelength_m
    f = np.fft.fftfreq(n_chirps, config.pri_s)
    shaped = np.fft.ifft(np.fft.fft(rng.standard_normal((n_chirps, n_samples))
                                    + 1j * rng.standard_normal((n_chirps, n_samples)), axis=0)
                         * np.exp(-0.25 * (f / sigma_hz) ** 2)[:, None], axis=0)
    moving = shaped @ np.exp(1j * kappa * np.outer(ranges[:n_samples] - lo, tk))
    moving *= math.sqrt(0.5 * power / max(float(np.mean(np.abs(moving) ** 2)), 1e-300))
    return (static + moving).astype(np.complex64)


def _noise_cube(n_chirps: int, n_samples: int, power: float, rng: np.random.Generator) -> np.ndarray:
    """Complex white Gaussian noise scaled to exactly `power` per sample."""
    noise = rng.standard_normal((n_chirps, 2 * n_samples), dtype=np.float32).view(np.complex64)
    noise *= np.float32(math.sqrt(power * noise.size / float(np.vdot(noise, noise).real)))
    return noise


def render(scene: Scene, config: RadarConfig, n_chirps: int, n_samples: int,
           seed: int | None = None) -> Components:
    """Target, clutter and noise cubes of a scene (complex64). Deterministic given seed."""
    rng = np.random.default_rng(seed)
    target, truth = _target_cube(scene, config, n_chirps, n_samples, rng)
    truth = Truth(**{**truth.__dict__, "range_offset_m": config.range_offset_m})
    noise_power = 1.0 if scene.kind == "none" else (
        None if scene.snr_db is None else 10 ** (-scene.snr_db / 10))
    clutter = None
    nz = scene.nuisance
    clutter_power = None
    if scene.clutter_db is not None and noise_power is not None:
        clutter_power = noise_power * 10 ** (scene.clutter_db / 10)
    elif scene.clutter_to_signal_db is not None:  # the target's power per IF sample is 1
        clutter_power = 10 ** (scene.clutter_to_signal_db / 10)
    if clutter_power is not None:
        clutter = _clutter_cube(config, n_chirps, n_samples, clutter_power, rng,
                                nz.clutter_spread_mps if nz else 0.0)
    noise = None if noise_power is None else _noise_cube(n_chirps, n_samples, noise_power, rng)
    if nz is None:
        return Components(target, clutter, noise, truth)
    return Components(target, clutter, noise, truth, receiver=nz, receiver_seed=int(rng.integers(0, 2**63 - 1)),
                      noise_power=noise_power or 0.0)


def centred_offset(preset: Preset, range_m: float, radial_speed_mps: float = 0.0) -> float:
    """Range-gate start that puts the target's mid-dwell range mid-window (whole metres, >= 0)."""
    mid = range_m + radial_speed_mps * preset.dwell_s / 2
    return float(max(0.0, math.floor(mid - preset.window_m / 2)))


def simulate(scene: Scene, preset: Preset, seed: int | None = None, *,
             range_offset_m: float | None = None, site: RadarSite = DEFAULT_SITE,
             start_time: datetime = DEFAULT_START, dtype: type = np.complex64) -> tuple[Recording, Truth]:
    """Simulate one dwell of `preset` on `scene` into a Recording (+ its ground truth), in the
    preset's domain (`signatures.sim.domain.as_recorded`: a `cw` preset's cube is its CW samples)."""
    offset = centred_offset(preset, scene.range_m, scene.radial_speed_mps) if range_offset_m is None \
        else range_offset_m
    if preset.domain == "cw":
        offset = 0.0  # a CW radar has no range gate (docs/format.md)
    config = preset.with_offset(offset)
    comps = render(scene, config, preset.n_chirps, preset.n_samples, seed)
    iq = comps.total(dtype)
    rec = Recording(config=config, site=site, start_time=start_time, iq=iq,
                    simulation=truth_json(scene, comps.truth, preset.name, seed))
    return as_recorded(rec, preset.domain), comps.truth


def simulate_many(multi: MultiScene, preset: Preset, seed: int | None = None, *,
                  range_offset_m: float | None = None, site: RadarSite = DEFAULT_SITE,
                  start_time: datetime = DEFAULT_START) -> tuple[Recording, list[Truth]]:
    """One dwell of `preset` on several targets (`MultiScene`): a truth per target, in order.

    Each target is rendered as alone (its own stream of `seed`) and scaled to its power over the
    common unit noise; the range gate is centred on the targets' mid-dwell ranges, and a target
    outside it is refused (a CW preset has no gate)."""
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(len(multi.targets) + 1)]
    cw = preset.domain == "cw"
    if range_offset_m is None:
        mids = [t.range_m + t.radial_speed_mps * preset.dwell_s / 2 for t in multi.targets]
        range_offset_m = 0.0 if cw else centred_offset(preset, 0.5 * (min(mids) + max(mids)))
    config = preset.with_offset(0.0 if cw else range_offset_m)
    lo, hi = config.range_window_m
    cube = np.zeros((preset.n_chirps, preset.n_samples), dtype=np.complex64)
    truths = []
    for i, (target, rng) in enumerate(zip(multi.targets, streams)):
        ends = (target.range_m, target.range_m + target.radial_speed_mps * preset.dwell_s)
        if not cw and not (lo <= min(ends) and max(ends) < hi):
            raise SignaturesError(f"targets[{i}]: range {target.range_m:g} m leaves the gate [{lo:g}, {hi:g}) m")
        part, truth = _target_cube(target, config, preset.n_chirps, preset.n_samples, rng)
        assert part is not None and target.snr_db is not None
        cube += part * np.float32(10 ** (target.snr_db / 20))
        truths.append(Truth(**{**truth.__dict__, "range_offset_m": config.range_offset_m}))
    rng = streams[-1]
    clutter_power = multi.clutter_power()
    if clutter_power is not None:
        cube += _clutter_cube(config, preset.n_chirps, preset.n_samples, clutter_power, rng)
    cube += _noise_cube(preset.n_chirps, preset.n_samples, 1.0, rng)
    doc = {"preset": preset.name, "seed": seed, "scene": multi.model_dump(mode="json"),
           "truths": [truth_doc(t) for t in truths]}
    rec = Recording(config=config, site=site, start_time=start_time, iq=cube,
                    simulation=json.dumps(doc, sort_keys=True, separators=(",", ":")))
    return as_recorded(rec, preset.domain), truths


def truth_json(scene: Scene, truth: Truth, preset: str, seed: int | None) -> str:
    """Canonical JSON of what was simulated, stored as the file attribute `simulation`."""
    doc = {"preset": preset, "seed": seed, "scene": scene.model_dump(mode="json"), "truth": truth_doc(truth)}
    return json.dumps(doc, sort_keys=True, separators=(",", ":"))


def truth_doc(truth: Truth) -> dict:
    """The truth as JSON-ready data: its fields plus the rates derived from them (mean mechanical
    rotor rate, blade-flash rate, and the per-rotor rate at which the blade pattern repeats)."""
    return {**truth.__dict__, "rotor_rates_hz": list(truth.rotor_rates_hz), "rotor_rate_hz": truth.rotor_rate_hz,
            "blade_flash_rate_hz": truth.blade_flash_rate_hz, "pattern_rates_hz": list(truth.pattern_rates_hz)}
