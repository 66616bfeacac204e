"""The held-out signal model is physically sane, exact, reproducible and independent of the
training simulator (docs/signal-model.md, "Held-out model")."""

from __future__ import annotations

import ast
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lab.heldout import render, simulate, unseen_profiles
from lab.heldout.synthesis import bessel_j, if_cube
from signatures.profiles import load_profiles, shipped_profiles
from signatures.radar import C, get_preset
from signatures.sim.scene import Scene

PACKAGE = Path(__file__).resolve().parents[2] / "signatures" / "heldout"


def _scene(slug: str = "m300", **kw) -> Scene:
    profiles = {**shipped_profiles(), **unseen_profiles()}
    return Scene(profile=profiles[slug], **{"range_m": 400.0, "snr_db": None, **kw})


def _doppler_of_peak(iq: np.ndarray, pre, bin_: int) -> float:
    """Radial velocity of the strongest slow-time line in range bins bin_-1..bin_+1."""
    rng_fft = np.fft.fft(iq * np.hanning(iq.shape[1])[None, :], axis=1)[:, bin_ - 1:bin_ + 2]
    spec = np.sum(np.abs(np.fft.fft(rng_fft * np.hanning(iq.shape[0])[:, None], axis=0)) ** 2, axis=1)
    f = np.fft.fftfreq(iq.shape[0], d=pre.config.pri_s)[int(np.argmax(spec))]
    return float(f * pre.config.doppler_wavelength_m(iq.shape[1]) / 2)


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_exact_delay_expansion_matches_the_direct_sum(preset: str) -> None:
    """The Jacobi-Anger synthesis equals the scatterer-by-scatterer sum of exact-delay tones."""
    pre = get_preset(preset)
    cfg = pre.with_offset(370.0)
    rng = np.random.default_rng(3)
    n, m, k = 16, 25, pre.n_samples
    centre = 400.0 + 7.0 * np.arange(n) * cfg.pri_s
    d = rng.uniform(-1.2, 1.2, (n, m)).astype(np.float32)
    v = rng.uniform(-160, 160, (n, m)).astype(np.float32)
    a = rng.uniform(0, 1, (n, m)).astype(np.float32)
    got = if_cube(centre, d, v, a, cfg, k)
    r = centre[:, None] + d.astype(np.float64)
    lam, s = C / cfg.carrier_hz, cfg.slope_hz_per_s
    tau = 2 * (r - cfg.range_offset_m) / C
    tk = np.arange(k) / cfg.sample_rate_hz
    want = np.einsum("ni,nik->nk", a * np.exp(1j * (4 * math.pi * r / lam - math.pi * s * tau ** 2)),
                     np.exp(2j * math.pi * (s * tau + 2 * v / lam)[:, :, None] * tk))
    assert got.dtype == np.complex64
    assert np.max(np.abs(got - want)) < 1e-3 * np.sqrt(np.mean(np.abs(want) ** 2))


def test_bessel_functions_match_scipy() -> None:
    from scipy.special import jv

    orders, z = np.arange(45), np.linspace(-20.0, 20.0, 41)
    assert np.max(np.abs(bessel_j(orders, z) - jv(orders[:, None], z[None, :]))) < 1e-12


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_target_in_its_range_bin_and_body_line_at_its_radial_velocity(preset: str) -> None:
    pre = get_preset(preset)
    scene = _scene("m600", range_m=523.4, radial_speed_mps=-6.3, blade_to_body_db=-10.0)
    rec, truth = simulate(scene, pre, seed=11)
    bin_m = rec.config.range_bin_m(rec.n_samples)
    mid_range = scene.range_m + scene.radial_speed_mps * pre.dwell_s / 2
    profile = np.sum(np.abs(np.fft.fft(rec.iq * np.hanning(rec.n_samples)[None, :], axis=1)) ** 2, axis=0)
    peak = int(np.argmax(profile))
    assert abs(rec.config.range_offset_m + peak * bin_m - mid_range) <= 1.0 * bin_m
    assert truth.range_offset_m == rec.config.range_offset_m
    v = _doppler_of_peak(rec.iq, pre, peak)
    assert abs(v - rec.config.fold_velocity(scene.radial_speed_mps, rec.n_samples)) \
        <= rec.config.doppler_bin_mps(rec.n_chirps)


@pytest.mark.parametrize(("slug", "blades"), [("phantom4", 2), ("tri-y3", 2)])
def test_blade_flashes_repeat_at_the_rotor_rate(slug: str, blades: int) -> None:
    """The envelope of the blade returns repeats at blades x rotor rate (2 flashes a turn for
    the collinear pair); the rates drawn stay within the hover spread of the profile's."""
    pre = get_preset("paper")
    scene = _scene(slug, range_m=300.0, elevation_deg=5.0, blade_to_body_db=-6.0)
    n = 6000  # 264 ms: 3.8 Hz resolution
    cfg = pre.with_offset(270.0)
    parts = render(scene, cfg, n, pre.n_samples, seed=5)
    rates = np.array(parts.truth.airframe.rotor_rates_hz)
    nominal = scene.profile.rotor_rate_hz
    assert np.all(np.abs(rates / nominal - 1) < 0.17)
    slow = np.fft.fft(parts.target, axis=1)[:, 30]  # the target's range bin
    envelope = np.abs(slow - slow.mean()) ** 2
    spec = np.abs(np.fft.rfft((envelope - envelope.mean()) * np.hanning(n))) ** 2
    f = np.fft.rfftfreq(n, d=cfg.pri_s)
    band = (f > 0.5 * blades * nominal) & (f < 1.6 * blades * nominal)
    flash = f[band][int(np.argmax(spec[band]))]
    res = 1.0 / (n * cfg.pri_s)
    assert blades * rates.min() - 2 * res <= flash <= blades * rates.max() + 2 * res


@pytest.mark.parametrize("snr_db", [0.0, 10.0])
def test_snr_is_target_over_noise_power_per_sample_after_the_receiver(snr_db: float) -> None:
    """The received cube carries the requested SNR within 0.5 dB, imperfections included."""
    parts = render(_scene("racer5", snr_db=snr_db, radial_speed_mps=3.0), get_preset("paper").with_offset(370.0),
                   600, 80, seed=2)
    p_noise = float(np.mean(np.abs(parts.noise) ** 2))
    assert float(np.mean(np.abs(parts.target) ** 2)) == pytest.approx(1.0, rel=1e-4)
    assert 10 * math.log10(1.0 / p_noise) == pytest.approx(snr_db, abs=1e-3)
    measured = 10 * math.log10((float(np.mean(np.abs(parts.iq) ** 2)) - p_noise) / p_noise)
    assert abs(measured - snr_db) < 0.5


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), slug=st.sampled_from(["m300", "octo-s1000", "racer5", "x8-coax", "tri-y3"]),
       speed=st.floats(-20.0, 20.0), clutter=st.one_of(st.none(), st.floats(-10.0, 30.0)))
def test_deterministic_complex64_and_finite(seed: int, slug: str, speed: float, clutter: float | None) -> None:
    scene = _scene(slug, snr_db=5.0, radial_speed_mps=speed, clutter_db=clutter)
    pre = get_preset("paper")
    a, ta = simulate(scene, pre, seed)
    b, _ = simulate(scene, pre, seed)
    assert a.iq.dtype == np.complex64 and a.iq.shape == (600, 80)
    assert np.all(np.isfinite(a.iq)) and np.array_equal(a.iq, b.iq)
    assert not np.array_equal(a.iq, simulate(scene, pre, seed + 1)[0].iq)
    doc = json.loads(a.simulation)
    assert doc["model"].startswith("heldout/") and doc["truth"]["label"] == slug
    assert len(ta.airframe.rotor_rates_hz) == scene.profile.rotors


def test_removing_noise_leaves_the_target_bit_identical() -> None:
    cfg = get_preset("paper").with_offset(370.0)
    noisy = render(_scene(snr_db=0.0, clutter_db=10.0), cfg, 600, 80, seed=9)
    clean = render(_scene(snr_db=None), cfg, 600, 80, seed=9)
    assert np.array_equal(noisy.target, clean.target) and clean.noise is None and clean.clutter is None


def test_shares_no_code_with_the_training_simulator() -> None:
    """No module of the package imports signatures.sim.simulate (or its sampler and datasets), and
    importing the package does not load them."""
    banned = {"signatures.sim.simulate", "signatures.sim.sampling", "signatures.train.dataset", "signatures.sim.domain"}
    for path in PACKAGE.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + [f"{node.module}.{a.name}" for a in node.names]
            assert not banned & set(names), f"{path.name} imports {banned & set(names)}"
    code = "import sys, lab.heldout; print(sorted(m for m in sys.modules if m in %r))" % (banned,)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_unseen_profiles_load_and_were_never_trained_on() -> None:
    unseen = unseen_profiles()
    openset = load_profiles(Path(__file__).resolve().parents[2] / "signatures" / "data" / "openset_profiles.json")
    assert not set(unseen) & (set(shipped_profiles()) | set(openset))
    assert any(p.rotors == 8 and p.arms == 8 for p in unseen.values())  # octocopter
    assert any(p.blades_per_rotor == 3 and p.rotor_rate_hz >= 350 and p.blade_length_m < 0.07
               for p in unseen.values())  # 5-inch racer
    assert any(p.rotors == 2 * p.arms or p.rotors == 3 for p in unseen.values())  # coaxial X8 or tricopter


def test_birds_render_with_their_own_truth() -> None:
    """The held-out bird (point wings, asymmetric stroke) puts its flap rate in the truth and its
    micro-Doppler stays slow: 99 % of its Doppler power within a few m/s of the body line."""
    parts = render(Scene(kind="bird", range_m=100.0, snr_db=None), get_preset("wide").config, 8192, 64, seed=0)
    assert parts.truth.bird is not None and parts.truth.airframe is None
    assert abs(parts.truth.bird.flap_rate_hz - 6.0) < 0.2
    spec = np.sum(np.abs(np.fft.fftshift(np.fft.fft(parts.target, axis=0), axes=0)) ** 2, axis=1)
    cfg = get_preset("wide").config
    v = np.fft.fftshift(np.fft.fftfreq(8192, cfg.pri_s)) * cfg.wavelength_m / 2
    assert spec[np.abs(v) < 6.0].sum() > 0.99 * spec.sum()
