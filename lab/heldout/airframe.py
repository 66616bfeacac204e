"""The held-out airframe as point scatterers in motion (docs/signal-model.md, "Held-out model").

A multirotor here is a cloud of points, not line blades: fuselage points, arms that flex,
motors that vibrate at their own rotor rate, spinners on the hubs, landing gear, and along
each blade 8-12 stations with a tip-heavy RCS taper, a swept (curved) planform, coning and
a few tenths of a millimetre of thickness, each station with a specular lobe around
broadside. Rotors turn at their own rates (hover/climb +-10 % of nominal, a spread of a few
per cent, differential thrust when moving, coaxial lower rotors faster), with random phases
and diagonal pairs counter-rotating. The attitude wobbles with a pink spectrum and the yaw
drifts. Everything is expressed per chirp as each point's offset along the line of sight
and its distance from the body centre, from which `synthesis` takes the exact range.

One scene is one airframe (`airframe_stream`): its layout, the rates it flies, its blades, body
and tags are drawn from the scene, so the dwells of a track differ only in what a real track's
dwells differ in (attitude, blade phases, noise).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass

import numpy as np

from signatures.profiles import UavProfile
from signatures.sim.scene import Scene


@dataclass(frozen=True)
class Points:
    """Scatterers over one dwell: (n_chirps, n_points) float32 arrays (1e-7 m near a 1 m body)."""

    along_los: np.ndarray  # offset from the body centre projected on the line of sight, m
    norm_sq: np.ndarray  # squared distance from the body centre, m^2 (exact range needs it)
    amplitude: np.ndarray  # real field amplitude (aspect pattern included)


@dataclass(frozen=True)
class AirframeTruth:
    rotor_rates_hz: tuple[float, ...]
    spin: tuple[int, ...]
    stations_per_blade: int
    blade_to_body_db: float
    attitude_rms_deg: float
    tilt_deg: float
    n_points: int
    blades_per_rotor: int = 2
    #: per rotor and blade: the tag's (or the scene's weight's) power gain in dB over the blade's
    #: own RCS, 0 where none; () when the scene tags nothing
    tag_db: tuple[tuple[float, ...], ...] = ()

    @property
    def pattern_rates_hz(self) -> tuple[float, ...]:
        """Per rotor, the rate at which its flash pattern repeats: its mechanical rate when a tag or
        a weight makes its blades unequal, else its flash rate (the model's own +-1.5 dB blade
        spread aside)."""
        n = self.blades_per_rotor
        per_turn = n if n % 2 == 0 else 2 * n
        return tuple(f if self.tag_db and max(self.tag_db[i]) - min(self.tag_db[i]) > 1e-6 else per_turn * f
                     for i, f in enumerate(self.rotor_rates_hz))


def _rotate(v: np.ndarray, axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: rotate vectors v (..., 3) about unit axes (..., 3) by angle (...)."""
    c = np.cos(angle)[..., None]
    s = np.sin(angle)[..., None]
    dot = np.sum(axis * v, axis=-1, keepdims=True)
    return v * c + np.cross(axis, v) * s + axis * dot * (1.0 - c)


def _pink_wobble(rng: np.random.Generator, t: np.ndarray, rms_rad: float, parts: int = 6) -> np.ndarray:
    """A sum of sinusoids 0.3-8 Hz with amplitude ~ 1/f, scaled to `rms_rad`."""
    f = np.exp(rng.uniform(math.log(0.3), math.log(8.0), parts))
    amp = 1.0 / f
    amp *= rms_rad / math.sqrt(0.5 * float(np.sum(amp ** 2)))
    ph = rng.uniform(0.0, 2 * math.pi, parts)
    return np.sin(2 * math.pi * f[None, :] * t[:, None] + ph[None, :]) @ amp


def line_of_sight_in_body(scene: Scene, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, float, float,
                                                                                           float]:
    """Radar-to-target unit vector in body axes per chirp (n, 3); the initial yaw, the
    attitude wobble's rms and the mean tilt (both degrees)."""
    el = math.radians(scene.elevation_deg)
    los = np.array([math.cos(el), 0.0, math.sin(el)])
    v_h = scene.radial_speed_mps * math.cos(el)
    tilt = math.radians(min(25.0, rng.uniform(0.8, 1.3) * abs(v_h)))  # nose down into the motion
    rms = math.radians(rng.uniform(0.4, 2.0) * scene.attitude_wobble_deg)
    rot_vec = np.zeros((t.size, 3))
    rot_vec[:, 0] = _pink_wobble(rng, t, rms)
    rot_vec[:, 1] = math.copysign(tilt, v_h) + _pink_wobble(rng, t, rms)
    yaw0 = math.radians(scene.yaw_deg) if scene.yaw_deg is not None else rng.uniform(0.0, 2 * math.pi)
    yaw = yaw0 + math.radians(rng.uniform(-8.0, 8.0)) * t
    angle = np.linalg.norm(rot_vec, axis=1)
    axis = rot_vec / np.maximum(angle, 1e-15)[:, None]
    w = _rotate(np.broadcast_to(los, (t.size, 3)), axis, -angle)  # undo the tilt ...
    w = _rotate(w, np.broadcast_to([0.0, 0.0, 1.0], (t.size, 3)), -yaw)  # ... then the yaw
    return w, yaw0, math.degrees(rms), math.degrees(tilt)


@dataclass(frozen=True)
class _Layout:
    hubs: np.ndarray  # (r, 3) rotor centres in body axes
    e1: np.ndarray  # (r, 3) rotor-plane basis
    e2: np.ndarray
    normal: np.ndarray  # (r, 3) rotor axis
    spin: np.ndarray  # (r,) +1 / -1
    lower: np.ndarray  # (r,) bool: lower rotor of a coaxial pair
    arm_dirs: np.ndarray  # (arms, 3) unit vectors of the arms used


def _layout(p: UavProfile, rng: np.random.Generator) -> _Layout:
    per = max(1, p.rotors // p.arms)
    step = max(1, p.arms // p.rotors)
    arm_of = (np.arange(p.rotors) // per) * step
    alpha0 = rng.choice([0.0, math.pi / p.arms])  # "+" or "x" flying direction
    alpha = alpha0 + 2 * math.pi * arm_of / p.arms
    radius = 0.5 * p.propeller_distance_m
    lower = (np.arange(p.rotors) % per == 1) if per > 1 else np.zeros(p.rotors, bool)
    if per > 1:
        z = np.where(lower, -1.0, 1.0) * float(np.clip(0.07 * p.propeller_distance_m, 0.04, 0.10))
    else:
        z = np.full(p.rotors, float(np.clip(0.05 * p.propeller_distance_m, 0.015, 0.06)))
    hubs = np.stack([radius * np.cos(alpha), radius * np.sin(alpha), z], axis=1)
    # each rotor axis: a mount tilt up to 2 deg about a random horizontal axis; a tricopter's
    # tail rotor also leans 2-8 deg on its yaw servo, about its arm
    tilt = np.radians(rng.uniform(0.0, 2.0, p.rotors))
    az = rng.uniform(0.0, 2 * math.pi, p.rotors)
    axis = np.stack([np.cos(az), np.sin(az), np.zeros(p.rotors)], axis=1)
    if p.rotors == 3:
        tilt[0] = math.radians(rng.uniform(2.0, 8.0)) * rng.choice([-1.0, 1.0])
        axis[0] = [math.cos(alpha[0]), math.sin(alpha[0]), 0.0]
    basis = [_rotate(np.broadcast_to(e, (p.rotors, 3)), axis, tilt) for e in np.eye(3)]
    # diagonal pairs counter-rotating: neighbours alternate, coaxial partners oppose;
    # a tricopter's rotors are free (its yaw comes from the servo); the whole pattern may be mirrored
    if p.rotors == 3:
        spin = rng.choice([-1.0, 1.0], 3)
    else:
        spin = np.where(arm_of % 2 == 0, 1.0, -1.0) * np.where(lower, -1.0, 1.0)
    spin = spin * rng.choice([-1.0, 1.0])
    used = np.unique(alpha)
    arms = np.stack([np.cos(used), np.sin(used), np.zeros(used.size)], axis=1)
    return _Layout(hubs, basis[0], basis[1], basis[2], spin, lower, arms)


def _rotor_phases(p: UavProfile, lay: _Layout, scene: Scene, t: np.ndarray, yaw0: float,
                  build: np.random.Generator, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Blade-0 angle of every rotor per chirp (n, r) and each rotor's mean rate (r,): the rates
    flown from the airframe's stream `build`, phases and the controllers' hunting from the dwell's."""
    if scene.hovering:
        scale = build.uniform(0.90, 1.10)
    else:
        scale = build.uniform(0.95, 1.12)
    if scene.rotor_rate_hz is not None:  # the scene fixes the common rate flown (idle, say)
        scale = scene.rotor_rate_hz / p.rotor_rate_hz
    spread = np.clip(build.normal(0.0, build.uniform(0.01, 0.03), p.rotors), -0.06, 0.06)
    rates = p.rotor_rate_hz * scale * (1.0 + spread)
    rates = np.where(lay.lower, rates * build.uniform(1.03, 1.10), rates)  # the lower prop works in the upper's wash
    if not scene.hovering:  # pitching into the motion: front rotors slower, rear ones faster
        heading = np.array([math.cos(-yaw0), math.sin(-yaw0), 0.0]) * math.copysign(1.0, scene.radial_speed_mps)
        along = lay.hubs @ heading / max(float(np.max(np.linalg.norm(lay.hubs[:, :2], axis=1))), 1e-9)
        rates = rates * (1.0 - min(0.06, 0.004 * abs(scene.radial_speed_mps)) * along)
    depth = rng.uniform(0.0, 0.01, p.rotors)  # the speed controllers' hunting
    f_mod = rng.uniform(0.5, 4.0, p.rotors)
    psi = rng.uniform(0.0, 2 * math.pi, p.rotors)
    wander = depth / (2 * math.pi * f_mod) * (np.cos(2 * math.pi * f_mod * t[:, None] + psi) - np.cos(psi))
    theta = rng.uniform(0.0, 2 * math.pi, p.rotors) + lay.spin * 2 * math.pi * rates * (t[:, None] - wander)
    return theta, rates


def _blades(p: UavProfile, lay: _Layout, theta: np.ndarray, w: np.ndarray, wavelength: float,
            rng: np.random.Generator) -> tuple[Points, int]:
    """Blade stations and tips of every rotor (`rng`: the airframe's stream)."""
    n_st = int(rng.integers(8, 13))
    L = p.blade_length_m
    rho = L * (0.15 + 0.85 * (np.arange(n_st) + 0.5) / n_st)
    rho = np.append(rho, L)  # the tip: a diffracting edge, seen from every aspect
    taper = (rho / L) ** rng.uniform(0.3, 1.5)
    taper[-1] = rng.uniform(0.2, 0.5)
    sweep = np.sin(math.radians(rng.uniform(-4.0, 4.0)) * (rho / L) ** 2)  # curved planform
    sweep[-1] = 0.0
    lobe = np.float32(0.3 * wavelength / (0.85 * L / n_st))  # specular lobe of one station, in cos(aspect)
    floor = rng.uniform(0.05, 0.15)
    iso = np.zeros(n_st + 1)
    iso[-1] = 1.0
    cone = math.sin(math.radians(rng.uniform(1.0, 4.0)))
    lift = rho * cone + rng.normal(0.0, 0.8e-3, n_st + 1)  # coning plus blade thickness, along the rotor axis
    nb = p.blades_per_rotor
    spacing = 2 * math.pi * np.arange(nb) / nb + np.radians(rng.normal(0.0, 0.3, (p.rotors, nb)))
    gain = 10 ** (rng.normal(0.0, 1.5, (p.rotors, nb)) / 20)  # unequal blades
    ang = theta[:, :, None] + spacing[None]  # (n, r, b)
    c, s = np.cos(ang).astype(np.float32), np.sin(ang).astype(np.float32)
    w_e1 = (w @ lay.e1.T).astype(np.float32)  # (n, r)
    w_e2 = (w @ lay.e2.T).astype(np.float32)
    w_n = (w @ lay.normal.T).astype(np.float32)
    rho, lift, sweep, taper, iso = (x.astype(np.float32) for x in (rho, lift, sweep, taper, iso))
    aspect = c * w_e1[:, :, None] + s * w_e2[:, :, None]  # cos(blade axis, line of sight)
    hub_los = (w @ lay.hubs.T).astype(np.float32)
    along = (hub_los[:, :, None, None] + rho * aspect[..., None]
             + lift * w_n[:, :, None, None])  # (n, r, b, station)
    h_e1, h_e2, h_n, h_sq = (np.sum(lay.hubs * e, axis=1).astype(np.float32)[None, :, None, None]
                             for e in (lay.e1, lay.e2, lay.normal, lay.hubs))
    norm_sq = (h_sq + rho ** 2 + lift ** 2
               + 2 * rho * (c[..., None] * h_e1 + s[..., None] * h_e2) + 2 * lift * h_n)
    floor = np.float32(floor)
    pattern = iso + (1 - iso) * (floor + (1 - floor) * np.exp(-((aspect[..., None] - sweep) / lobe) ** 2))
    amp = taper * gain.astype(np.float32)[None, :, :, None] * pattern
    shape = (theta.shape[0], -1)
    return Points(along.reshape(shape), norm_sq.reshape(shape), amp.reshape(shape)), n_st


def _tags(scene: Scene, n_st: int, rng: np.random.Generator) -> tuple[np.ndarray | None, np.ndarray]:
    """Per-station amplitude factors (r, b, stations + 1) of the scene's tags or blade weights, and
    each blade's power gain in dB (r, b); None when the scene has neither.

    A tag here is a strip of reflective tape: it covers 2-4 adjacent stations at 45-90 % of the
    span (the tip point untouched), and raises those stations so that the blade's summed station
    power grows by the scene's `tag_gain_db`. The tagged blades are drawn from the held-out
    model's own stream (or named by `tag_pattern`). Blade weights scale a whole blade."""
    p = scene.profile
    assert p is not None
    r, b = p.rotors, p.blades_per_rotor
    if scene.blade_weights is not None:
        w = np.asarray(scene.blade_weights, dtype=np.float64)
        return np.broadcast_to(w[:, :, None], (r, b, n_st + 1)).copy(), 20 * np.log10(np.maximum(w, 1e-6))
    if scene.tag_pattern is not None:  # the blades named, rotor by rotor
        flat = [k for k, c in enumerate(scene.tag_pattern) if c == "1"]
    elif not scene.tagged_blades:
        return None, np.zeros((r, b))
    elif scene.tag_layout == "spread":  # one per rotor first (rotor order shuffled), then a second
        rotor_order = rng.permutation(r)
        flat = [int(rotor_order[k % r]) * b + (k // r) for k in range(scene.tagged_blades)]
    else:
        flat = list(rng.choice(r * b, size=scene.tagged_blades, replace=False))
    factor = np.ones((r * b, n_st + 1))
    db = np.zeros(r * b)
    gain = 10 ** (scene.tag_gain_db / 10)  # power of the blade with its tag over the blade without
    for k in flat:
        width = int(rng.integers(2, 5))
        first = int(rng.integers(int(0.45 * n_st), max(int(0.45 * n_st) + 1, int(0.9 * n_st) - width + 1)))
        strip = np.arange(first, min(first + width, n_st))
        # stations' powers sum; a strip of s stations of the n must carry (gain - 1) x n extra
        factor[k, strip] = math.sqrt(1.0 + (gain - 1.0) * n_st / strip.size)
        db[k] = scene.tag_gain_db
    return factor.reshape(r, b, n_st + 1), db.reshape(r, b)


def _body(p: UavProfile, lay: _Layout, rates: np.ndarray, t: np.ndarray, w: np.ndarray,
          rng: np.random.Generator) -> Points:
    """Fuselage, spinners, vibrating motors, flexing arms and landing gear (`rng`: the airframe's stream)."""
    D = p.propeller_distance_m
    pos, amp_db, disp_dir, disp = [], [], [], []  # displacement: a unit direction and its (n,) motion

    def add(x: np.ndarray, db: float, direction: np.ndarray | None = None, motion: np.ndarray | None = None) -> None:
        pos.append(x)
        amp_db.append(db)
        disp_dir.append(np.zeros(3) if direction is None else direction)
        disp.append(np.zeros(t.size) if motion is None else motion)

    for _ in range(int(rng.integers(3, 7))):
        add(rng.uniform(-1, 1, 3) * np.array([0.12, 0.08, 0.04]) * D, rng.normal(-4.0, 3.0))
    for r in range(p.rotors):
        add(lay.hubs[r] + 0.015 * lay.normal[r], -14.0)  # spinner
        buzz = rng.uniform(10e-6, 60e-6) * np.sin(2 * math.pi * rates[r] * t + rng.uniform(0, 2 * math.pi))
        add(lay.hubs[r] - 0.03 * lay.normal[r], -8.0, lay.normal[r], buzz)  # motor can
    for arm in lay.arm_dirs:
        flex = rng.uniform(0.05e-3, 0.3e-3) * np.sin(2 * math.pi * rng.uniform(8.0, 25.0) * t
                                                      + rng.uniform(0, 2 * math.pi))
        for frac, share in ((0.35, 0.3), (0.7, 1.0)):
            add(arm * frac * 0.5 * D, -13.0, np.array([0.0, 0.0, 1.0]), share * flex)
    if D >= 0.5:
        for sx in (-1, 1):
            for sy in (-1, 1):
                add(np.array([0.18 * sx, 0.15 * sy, -0.22]) * D, -11.0)
    x = np.array(pos)  # (m, 3)
    u = np.array(disp_dir)
    eta = np.array(disp).T  # (n, m)
    along = w @ x.T + eta * (w @ u.T)
    norm_sq = np.sum(x ** 2, axis=1)[None, :] + 2 * eta * np.sum(x * u, axis=1)[None, :] + eta ** 2
    amp = np.broadcast_to(10 ** (np.array(amp_db) / 20), along.shape)
    return Points(along.astype(np.float32), norm_sq.astype(np.float32), amp.astype(np.float32))


#: Scene fields that are not the airframe: where it is and what surrounds it.
NOT_AIRFRAME = {"range_m", "snr_db", "clutter_db", "clutter_to_signal_db"}


def airframe_stream(scene: Scene) -> np.random.Generator:
    """The random stream an airframe is built from: keyed by the scene without its range and its
    surroundings (`NOT_AIRFRAME`), so that the dwells of one track (one scene whose range moves on,
    `lab.bench.track`) see one airframe, flown at one rate with one set of blades, as a real track
    does, while the dwell's own seed draws what changes from dwell to dwell (attitude, blade
    phases, noise); the same scene at another SNR is the same airframe."""
    unset = {"tag_pattern"} if scene.tag_pattern is None else set()  # scenes without one keep their airframe
    key = json.dumps(scene.model_dump(mode="json", exclude=NOT_AIRFRAME | unset), sort_keys=True,
                     separators=(",", ":"))
    digest = hashlib.sha256(f"heldout-airframe/1:{key}".encode()).digest()
    return np.random.default_rng(int.from_bytes(digest[:16], "big"))


def uav_points(scene: Scene, t: np.ndarray, wavelength: float,
               rng: np.random.Generator) -> tuple[Points, AirframeTruth]:
    """Every scatterer of the scene's UAV over the dwell; blades scaled to their power share. The
    airframe (layout, rates flown, blades, body, tags) comes from `airframe_stream(scene)`, the
    dwell's attitude and phases from `rng`."""
    p = scene.profile
    assert p is not None
    build = airframe_stream(scene)
    w, yaw0, rms_deg, tilt_deg = line_of_sight_in_body(scene, t, rng)
    lay = _layout(p, build)
    theta, rates = _rotor_phases(p, lay, scene, t, yaw0, build, rng)
    blades, n_st = _blades(p, lay, theta, w, wavelength, build)
    body = _body(p, lay, rates, t, w, build)
    # blade share by RCS (incoherent): -16..-6 dB of the body unless the scene sets it
    ratio_db = scene.blade_to_body_db if scene.blade_to_body_db is not None else float(build.uniform(-16.0, -6.0))
    p_body = float(np.sum(body.amplitude[0] ** 2))
    p_blades = float(np.mean(np.sum(blades.amplitude ** 2, axis=1)))
    k = np.float32(math.sqrt(p_body / p_blades * 10 ** (ratio_db / 10)))
    tag_factor, tag_db = _tags(scene, n_st, build)  # drawn last: an untagged scene is unchanged
    if tag_factor is not None:  # a tag adds RCS on top of the blade's share
        blades = Points(blades.along_los, blades.norm_sq,
                        blades.amplitude * tag_factor.reshape(-1).astype(np.float32)[None, :])
    pts = Points(np.concatenate([body.along_los, blades.along_los], axis=1),
                 np.concatenate([body.norm_sq, blades.norm_sq], axis=1),
                 np.concatenate([body.amplitude, k * blades.amplitude], axis=1))
    truth = AirframeTruth(tuple(float(r) for r in rates), tuple(int(s) for s in lay.spin), n_st, ratio_db,
                          rms_deg, tilt_deg, int(pts.amplitude.shape[1]), p.blades_per_rotor,
                          () if tag_factor is None else tuple(tuple(float(x) for x in row) for row in tag_db))
    return pts, truth
