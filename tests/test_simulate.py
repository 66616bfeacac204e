"""Simulator physics against closed-form results."""

from __future__ import annotations

import math

import numpy as np
import pytest

from signatures.profiles import UavProfile, shipped_profiles
from signatures.radar import get_preset
from signatures.sim.scene import Scene
from signatures.sim.simulate import render, simulate

PROFILES = shipped_profiles()


def _clean(slug: str = "m300", **kw) -> Scene:
    base = dict(profile=PROFILES[slug], snr_db=None, elevation_deg=0.0, attitude_wobble_deg=0.0,
                rotor_rate_jitter=0.0, yaw_deg=0.0)
    base.update(kw)
    return Scene(kind="uav", **base)


def _range_profile(iq: np.ndarray) -> np.ndarray:
    spec = np.fft.fft(iq.astype(np.complex128) * np.hanning(iq.shape[1]), axis=1)
    return np.mean(np.abs(spec) ** 2, axis=0)


@pytest.mark.parametrize("preset_name", ["paper", "wide"])
@pytest.mark.parametrize("frac", [0.05, 0.3, 0.55, 0.8, 0.95])
def test_range_peak_at_commanded_range(preset_name: str, frac: float) -> None:
    pre = get_preset(preset_name)
    offset = 400.0
    r = offset + frac * pre.window_m
    rec, _ = simulate(_clean(range_m=r), pre, seed=1, range_offset_m=offset)
    k = int(np.argmax(_range_profile(rec.iq)))
    measured = offset + k * rec.config.range_bin_m(rec.n_samples)
    assert abs(measured - r) <= rec.config.range_bin_m(rec.n_samples)


@pytest.mark.parametrize("preset_name", ["paper", "wide"])
@pytest.mark.parametrize("speed", [0.0, 3.3, -7.9, 15.0, -21.0, 30.0, -41.5])
def test_bulk_doppler_gives_radial_velocity_with_spec_sign(preset_name: str, speed: float) -> None:
    pre = get_preset(preset_name)
    rec, _ = simulate(_clean("phantom4", range_m=600.0, radial_speed_mps=speed), pre, seed=2)
    cfg = rec.config
    k = int(np.argmax(_range_profile(rec.iq)))
    # the target migrates across range bins at high speed: add the Doppler power of its bins
    slow = np.fft.fft(rec.iq.astype(np.complex128) * np.hanning(rec.n_samples), axis=1)[:, max(k - 3, 0):k + 4]
    spec = np.sum(np.abs(np.fft.fftshift(np.fft.fft(slow * np.hanning(slow.shape[0])[:, None], axis=0),
                                         axes=0)) ** 2, axis=1)
    freqs = np.fft.fftshift(np.fft.fftfreq(slow.shape[0], cfg.pri_s))
    measured = freqs[int(np.argmax(spec))] * cfg.doppler_wavelength_m(rec.n_samples) / 2
    expected = cfg.fold_velocity(speed, rec.n_samples)
    bin_mps = cfg.doppler_bin_mps(rec.n_chirps)
    wrapped = (measured - expected + cfg.unambiguous_velocity_mps) % (2 * cfg.unambiguous_velocity_mps) \
        - cfg.unambiguous_velocity_mps
    assert abs(wrapped) <= bin_mps
    if abs(speed) >= cfg.unambiguous_velocity_mps:
        assert abs(measured - speed) > cfg.unambiguous_velocity_mps  # folded, as physics says


@pytest.mark.parametrize("preset_name", ["paper", "wide"])
@pytest.mark.parametrize("slug", sorted(PROFILES))
def test_blade_flash_period_is_blades_times_rotor_rate(preset_name: str, slug: str) -> None:
    """With no jitter or wobble the rotor signal repeats exactly every 1/(N*f_rot).

    The aliased blade signal decorrelates within a fraction of a PRI, so the rotor
    rate is nudged (< 0.5 %) to make the flash period a whole number of chirps.
    """
    pre = get_preset(preset_name)
    p = PROFILES[slug]
    period_chirps = round(1.0 / (p.blade_flash_rate_hz * pre.config.pri_s))
    rate = 1.0 / (p.blades_per_rotor * period_chirps * pre.config.pri_s)
    assert rate == pytest.approx(p.rotor_rate_hz, rel=5e-3)
    scene = _clean(slug, range_m=300.0).model_copy(update={"profile": p.replace(rotor_rate_hz=rate)})
    rec, truth = simulate(scene, pre, seed=3)
    k = int(np.argmax(_range_profile(rec.iq)))
    slow = np.fft.fft(rec.iq.astype(np.complex128), axis=1)[:, k]
    slow = slow - slow.mean()  # the hovering body and hubs are constant: keep the blades
    lags = np.arange(int(0.4 * period_chirps), min(int(1.6 * period_chirps), slow.size - 50))
    corr = np.array([abs(np.vdot(slow[:-lag], slow[lag:])) / np.vdot(slow[:-lag], slow[:-lag]).real
                     for lag in lags])
    assert truth.blade_flash_rate_hz == pytest.approx(2 * rate, rel=1e-9)
    assert lags[int(np.argmax(corr))] == period_chirps
    assert corr.max() > 0.95


@pytest.mark.parametrize("slug", sorted(PROFILES))
def test_wide_preset_max_micro_doppler_is_tip_doppler(slug: str) -> None:
    pre = get_preset("wide")
    rec, truth = simulate(_clean(slug, range_m=200.0), pre, seed=4)
    k = int(np.argmax(_range_profile(rec.iq)))
    slow = np.fft.fft(rec.iq.astype(np.complex128), axis=1)[:, k]
    slow = slow - slow.mean()
    spec = np.abs(np.fft.fftshift(np.fft.fft(slow * np.hanning(slow.size)))) ** 2
    freqs = np.fft.fftshift(np.fft.fftfreq(slow.size, rec.config.pri_s))
    f_max = np.max(np.abs(freqs[spec > spec.max() * 1e-4]))  # -40 dB edge of the blade spectrum
    expected = 2 * truth.tip_speed_mps / rec.config.wavelength_m
    assert f_max == pytest.approx(expected, rel=0.05)
    assert not rec.config.tip_aliases(PROFILES[slug])
    assert get_preset("paper").config.tip_aliases(PROFILES[slug])


@pytest.mark.parametrize("snr", [-20.0, 0.0, 7.3, 35.0, 80.0])
@pytest.mark.parametrize("kind", ["uav", "bird"])
def test_snr_is_hit(snr: float, kind: str) -> None:
    pre = get_preset("paper")
    scene = Scene(kind=kind, profile=PROFILES["m600"] if kind == "uav" else None, range_m=250.0, snr_db=snr,
                  clutter_db=15.0)
    rec, _ = simulate(scene, pre, seed=5)
    clean = render(scene.model_copy(update={"snr_db": None, "clutter_db": None}), rec.config,
                   pre.n_chirps, pre.n_samples, seed=5)
    comps = render(scene, rec.config, pre.n_chirps, pre.n_samples, seed=5)
    noise = rec.iq.astype(np.complex128) - clean.target - comps.clutter
    measured = 10 * math.log10(np.mean(np.abs(clean.target) ** 2) / np.mean(np.abs(noise) ** 2))
    assert measured == pytest.approx(snr, abs=0.2)


def test_deterministic_and_float32() -> None:
    pre = get_preset("paper")
    scene = Scene(profile=PROFILES["m600"], range_m=900.0, radial_speed_mps=-4.0, snr_db=5.0, clutter_db=10.0)
    a, _ = simulate(scene, pre, seed=11)
    b, _ = simulate(scene, pre, seed=11)
    c, _ = simulate(scene, pre, seed=12)
    assert a.iq.dtype == np.complex64
    assert np.array_equal(a.iq, b.iq)
    assert not np.array_equal(a.iq, c.iq)
    d, _ = simulate(scene, pre, seed=11, dtype=np.complex128)
    assert d.iq.dtype == np.complex128


def test_scene_skips_what_it_does_not_contain() -> None:
    pre = get_preset("paper")
    cfg = pre.config
    none = render(Scene(kind="none", clutter_db=20.0), cfg, pre.n_chirps, pre.n_samples, seed=1)
    assert none.target is None and none.clutter is not None and none.noise is not None
    quiet = render(_clean(range_m=30.0), cfg, pre.n_chirps, pre.n_samples, seed=1)
    assert quiet.clutter is None and quiet.noise is None
    # stationary clutter: identical in every chirp
    assert np.allclose(none.clutter, none.clutter[:1])


def test_bird_has_small_micro_doppler() -> None:
    """Wing tips move at a few m/s; rotor tips at ~100 m/s: the spread differs by far."""
    pre = get_preset("wide")

    def spread(scene: Scene) -> float:
        rec, _ = simulate(scene, pre, seed=6)
        k = int(np.argmax(_range_profile(rec.iq)))
        slow = np.fft.fft(rec.iq.astype(np.complex128), axis=1)[:, k]
        spec = np.abs(np.fft.fft(slow - slow.mean())) ** 2
        freqs = np.fft.fftfreq(slow.size, pre.config.pri_s)
        return float(np.sqrt(np.sum(freqs**2 * spec) / np.sum(spec))) * pre.config.wavelength_m / 2

    bird = spread(Scene(kind="bird", range_m=150.0, snr_db=None, elevation_deg=0.0))
    uav = spread(_clean("phantom4", range_m=150.0))
    assert bird < 10.0 < uav


def test_new_profile_is_data_not_code() -> None:
    octo = UavProfile(slug="octo", name="Test octocopter", rotors=8, arms=8, blade_length_m=0.35,
                      rotor_rate_hz=45.0, propeller_distance_m=1.0)
    rec, truth = simulate(Scene(profile=octo, range_m=100.0, snr_db=None), get_preset("paper"), seed=1)
    assert truth.label == "octo" and len(truth.rotor_rates_hz) == 8
    assert np.isfinite(rec.iq).all()
