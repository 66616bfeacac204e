"""Estimators on long, low-PRF CW dwells of a hovering quadcopter with tagged blades (the
conditions of a real S-band radar: lab/accuracy.py CONDITIONS), in the training simulator and
in the held-out world: the body reads ~0 m/s, the rotor rate comes from the flash train's
envelope spectrum (signatures.dsp.flash_spectrum.spectral_flash_rate), and a periodic train is a detection
even where clutter suppression left no Doppler line. Shares measured on 20 seeded scenes; the
figures in docs/features.md come from `authn features accuracy --condition ...`."""

from __future__ import annotations

import functools
import json
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lab.accuracy import evaluate_condition, feature_estimate
from signatures.dsp import flash_spectrum as flash
from signatures.features import extract
from signatures.profiles import shipped_profiles
from signatures.radar import EXTRA_PRESETS
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate

pytestmark = pytest.mark.slow  # ~20 s: 160 simulated 0.82 s dwells


#: Levels measured on these 20 seeded scenes (docs/features.md has 40-scene rows). The rotor count
#: is of the rotors visible above the noise (`signatures.dsp.rotor_lines`), a lower bound: it never
#: counts more than the rotors (noise is no rotor), and it sees at least one in most scenes; untagged
#: rotors sit near the floor in 0.82 s, so "all four" is not asked (`lab.rotor_lines` shows no count
#: could see them all at this false-alarm rate).
@pytest.mark.parametrize(("condition", "world", "velocity", "rate", "some_rotor"), [
    ("cw-hover-tagged", "training", 0.9, 0.9, 0.9),
    ("cw-hover-tagged", "heldout", 0.95, 0.65, 0.75),
    ("cw-idle-tagged", "training", 0.85, 0.8, 0.9),
    ("cw-idle-tagged", "heldout", 0.95, 0.65, 0.9),
    # flying 2-12 m/s over clutter that sways in the held-out world: before the body's line was looked
    # for off the clutter's (and the clutter's left out of the envelope), 0 of 20 read within 1 m/s
    ("cw-moving-tagged", "training", 0.95, 0.9, 0.9),
    ("cw-moving-tagged", "heldout", 0.85, 0.6, 0.6),
])
def test_tagged_quad_on_a_cw_radar(condition, world, velocity, rate, some_rotor):
    counts: list[float] = []

    def recorded(rec):
        e = feature_estimate(rec)
        counts.append(e.rotors_seen)
        return e

    row = evaluate_condition(condition, n=20, seed=0, world=world, estimate=recorded)
    assert row.detected >= 0.9
    assert row.velocity_ok >= velocity
    assert row.rotor_ok >= rate
    assert row.rotor_median_err <= 0.03
    assert row.at_half <= 0.1  # the turn of a tagged blade is not read as its flash rate
    assert max(counts) <= 4 + 1  # a quad: never more rotors than it has (one residue line aside)
    assert np.mean(np.asarray(counts) >= 1) >= some_rotor


def test_noise_and_clutter_alone_are_no_flash_train():
    preset = EXTRA_PRESETS["cw-sband"]
    for seed in range(30):
        rec, _ = simulate(Scene(kind="none", snr_db=(0, 10, 20)[seed % 3], clutter_db=(None, 40)[seed % 2]),
                          preset, seed=seed)
        x = np.asarray(rec.iq)[None].astype(np.complex64)
        assert flash.spectral_flash_rate(x, rec.config, np.zeros(1)).score[0] < flash.SPECTRAL_DETECT_SCORE


def _flashes(t: np.ndarray, rate: float) -> np.ndarray:
    """Gaussian flashes at `rate` (3 % of a period wide) at times `t` (s), peak 1."""
    phase = (t * rate) % 1.0
    return np.exp(-0.5 * (np.minimum(phase, 1 - phase) / 0.03) ** 2)


def test_spectral_rate_is_refined_below_a_bin():
    """A pure flash train at a rate between bins: within 0.5 % of the rate (a bin is 1.2 Hz)."""
    preset = EXTRA_PRESETS["cw-sband"]
    config, n = preset.config, preset.n_chirps
    rng = np.random.default_rng(0)
    t = np.arange(n) * config.pri_s
    for rate in (97.3, 151.7, 333.3):
        flashes = _flashes(t, rate)
        doppler = np.exp(2j * math.pi * 900.0 * t) + np.exp(-2j * math.pi * 900.0 * t)
        x = (flashes * doppler + 0.05 * (rng.standard_normal(n) + 1j * rng.standard_normal(n)))[None, :, None]
        train = flash.spectral_flash_rate(x.astype(np.complex64), config, np.zeros(1))
        assert abs(train.rate_hz[0] - rate) <= 0.005 * rate, (rate, train.rate_hz[0])
        assert train.score[0] >= flash.SPECTRAL_DETECT_SCORE and 0 < train.rate_std_hz[0] < 1.0


def _line_width(spec: np.ndarray, pri_s: float) -> np.ndarray:
    """`flash_spectrum.line_width_hz` of Doppler spectra (B, pulses, bins) summed over their bins."""
    return flash.line_width_hz((spec.real ** 2 + spec.imag ** 2).sum(axis=2), pri_s)


def _moving_clutter(n: int, pri_s: float, spread_hz: float, amplitude: float, seed: int = 3) -> np.ndarray:
    """Clutter at zero Doppler with a Gaussian Doppler spread (foliage in the wind): white noise
    shaped in the Doppler domain, scaled to an rms `amplitude`."""
    rng = np.random.default_rng(seed)
    f = np.fft.fftfreq(n, d=pri_s)
    shaped = np.fft.ifft(np.fft.fft(rng.standard_normal(n) + 1j * rng.standard_normal(n))
                         * np.exp(-0.25 * (f / spread_hz) ** 2))
    return amplitude * shaped / np.sqrt(np.mean(np.abs(shaped) ** 2))


def test_moving_clutter_is_left_out_of_the_envelope():
    """A flash train under clutter 40 dB stronger whose Doppler spreads 10 Hz (rms) about zero:
    the clutter line's width is measured and the train read at its rate, where a fixed +-20 Hz
    band let the clutter's tails in as a slow wander that the rate locked onto."""
    preset = EXTRA_PRESETS["cw-sband"]
    config, n = preset.config, preset.n_chirps
    t = np.arange(n) * config.pri_s
    for rate in (131.3, 151.7, 333.3):
        flashes = _flashes(t, rate)
        doppler = np.exp(2j * math.pi * 900.0 * t) + np.exp(-2j * math.pi * 900.0 * t)
        x = flashes * doppler + _moving_clutter(n, config.pri_s, 10.0, 100.0)
        x = (x + 0.05 * (np.random.default_rng(0).standard_normal(n) + 1j))[None, :, None].astype(np.complex64)
        spec = np.fft.fft(x - x.mean(axis=1, keepdims=True), axis=1)
        assert 30.0 <= _line_width(spec, config.pri_s)[0] <= 120.0
        train = flash.spectral_flash_rate(x, config, np.zeros(1))
        assert abs(train.rate_hz[0] - rate) <= 0.005 * rate, (rate, train.rate_hz[0])


def test_a_flying_bodys_clutter_line_is_left_out_of_the_envelope():
    """The train of a body flying at 60-1100 Hz of Doppler (either way), under clutter 20 and 40 dB
    stronger that sways 10 Hz (rms) about zero: demodulated by the body, the clutter's line sits at
    minus its Doppler. Left in the envelope it read 28 of these 48 trains wrong (a multiple, a
    fraction, or the clutter's wander); dropped as far as it reaches, every one within 0.5 %."""
    preset = EXTRA_PRESETS["cw-sband"]
    config, n = preset.config, preset.n_chirps
    t = np.arange(n) * config.pri_s
    noise = 0.05 * (np.random.default_rng(0).standard_normal(n) + 1j)
    for body in (60.0, 150.0, 400.0, 1100.0, -700.0):
        for rate in (97.3, 131.3, 151.7, 333.3):
            blades = _flashes(t, rate) * (np.exp(2j * math.pi * 900.0 * t) + np.exp(-2j * math.pi * 900.0 * t))
            for amplitude in (10.0, 100.0):
                x = blades * np.exp(2j * math.pi * body * t) + _moving_clutter(n, config.pri_s, 10.0, amplitude)
                train = flash.spectral_flash_rate((x + noise)[None, :, None].astype(np.complex64), config,
                                                  np.array([body]))
                assert abs(train.rate_hz[0] - rate) <= 0.005 * rate, (body, rate, amplitude, train.rate_hz[0])


def test_an_accelerating_body_is_followed_over_sub_dwells():
    """A CW body flying at 5-9 m/s either way and accelerating at 1.5-2.5 m/s^2 (its line sweeps
    28-46 Hz, 23-38 bins, in 0.82 s), with tagged blades, at 0 dB per pulse under clutter 20 and
    40 dB stronger swaying 10 Hz about zero: its line stands under a single bin's bar, so the
    whole dwell read it hovering (0 of 32). Followed over sub-dwells it reads its mid-dwell
    speed within 1 m/s (30 of 32: at 5 m/s decelerating its line's first sub-dwells lie in the
    clutter's reach)."""
    from signatures.features import extract_iq

    preset = EXTRA_PRESETS["cw-sband"]
    config, n = preset.config, preset.n_chirps
    t = np.arange(n) * config.pri_s
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    blades = _flashes(t, 151.7) * (np.exp(2j * math.pi * 900.0 * t) + np.exp(-2j * math.pi * 900.0 * t))
    right = 0
    for v_mid in (-9.0, -6.0, 5.0, 8.0):
        for accel in (-2.5, -1.5, 1.5, 2.5):
            v = v_mid + accel * (t - t[n // 2])
            body = np.exp(2j * math.pi * np.cumsum(2.0 * v / config.wavelength_m) * config.pri_s)
            for amplitude in (10.0, 100.0):
                x = body * (1.0 + 0.5 * blades) + _moving_clutter(n, config.pri_s, 10.0, amplitude) + noise
                got = extract_iq(x[:, None].astype(np.complex64), config, domain="cw").features.radial_velocity_mps
                right += abs(got - v[n // 2]) < 1.0
    assert right >= 30
    for scale in (1e-30, 1e30):  # the cube is put on unit scale first: the same line at any scale
        scaled = extract_iq((x * scale)[:, None].astype(np.complex64), config, domain="cw").features
        assert scaled.radial_velocity_mps == pytest.approx(got, rel=1e-6)


def test_clutter_off_the_demodulation_does_not_leak_across_the_band():
    """Static clutter 40 dB over a flash train, the body read 0.3 Hz off zero (as moving clutter
    pulls it): demodulated by it, the clutter is a line that is not periodic in the record. Without
    the taper its window's sidelobes spread it across the band: the clutter read 624 Hz wide (the
    cap) and the train scored 0 or was read at twice its rate; tapered, the clutter is 60 Hz wide
    and the train scores as without clutter."""
    preset = EXTRA_PRESETS["cw-sband"]
    config, n = preset.config, preset.n_chirps
    t = np.arange(n) * config.pri_s
    rng = np.random.default_rng(4)
    for rate in (131.3, 333.3):
        flashes = _flashes(t, rate) * (np.exp(2j * math.pi * 900.0 * t) + np.exp(-2j * math.pi * 900.0 * t))
        noise = 0.05 * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
        clean = (flashes + noise)[None, :, None].astype(np.complex64)
        cluttered = (flashes + noise + 100.0)[None, :, None].astype(np.complex64)
        body = np.array([0.3])
        demod = cluttered * np.exp(-2j * math.pi * 0.3 * t)[None, :, None]
        spec = np.fft.fft((demod - demod.mean(axis=1, keepdims=True))
                          * flash.tukey(n, flash.ENVELOPE_TAPER)[None, :, None], axis=1)
        assert _line_width(spec, config.pri_s)[0] <= 100.0  # untapered: 624 Hz (the cap)
        train = flash.spectral_flash_rate(cluttered, config, body)
        alone = flash.spectral_flash_rate(clean, config, body)
        assert abs(train.rate_hz[0] - rate) <= 0.005 * rate and train.score[0] >= flash.SPECTRAL_DETECT_SCORE
        assert train.score[0] >= 0.5 * alone.score[0]


def test_the_taper_is_a_tukey_window():
    w = flash.tukey(1001, 0.1)
    assert w.dtype == np.float32 and w[0] == 0.0 and w[500] == 1.0 and np.all(w[50:951] == 1.0)
    assert np.allclose(w, w[::-1]) and np.all(np.diff(w[:51]) > 0)
    assert np.all(flash.tukey(10, 0.1) == 1.0)  # too short to taper


@settings(max_examples=10, deadline=None)
@given(spread_hz=st.floats(0.0, 15.0), log10_scale=st.floats(-20, 20))
def test_the_clutter_width_follows_the_spread_and_ignores_the_scale(spread_hz, log10_scale):
    """No clutter: the minimum band. Wider clutter: a wider band, never past an eighth of the PRF;
    the IQ scale changes nothing (a power ratio)."""
    config = EXTRA_PRESETS["cw-sband"].config
    n = 4096
    rng = np.random.default_rng(7)
    noise = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    clutter = _moving_clutter(n, config.pri_s, max(spread_hz, 1e-3), 100.0 if spread_hz > 0 else 0.0)
    x = (noise + clutter)[None, :, None]
    width = [_line_width(np.fft.fft(y - y.mean(axis=1, keepdims=True), axis=1), config.pri_s)[0]
             for y in (x, x * 10.0 ** log10_scale)]
    assert width[1] == pytest.approx(width[0])
    assert flash.SPECTRAL_BODY_HZ <= width[0] <= config.prf_hz / 8
    if spread_hz == 0.0:
        assert width[0] == flash.SPECTRAL_BODY_HZ
    if spread_hz >= 5.0:  # +40 dB: its tails reach past 3 spreads
        assert width[0] >= 3.0 * spread_hz


def _two_sided_train(rate: float, even: tuple[float, float], odd: tuple[float, float]) -> np.ndarray:
    """A CW dwell of Gaussian flashes at `rate`, each seen in the approaching (+900 Hz) and the
    receding (-900 Hz) half with the (approaching, receding) amplitudes of its parity: a rotor
    whose blades alternate sides at each flash."""
    preset = EXTRA_PRESETS["cw-sband"]
    n = preset.n_chirps
    t = np.arange(n) * preset.config.pri_s
    k = np.floor(t * rate + 0.5).astype(int)
    shape = _flashes(t, rate)
    amp = np.where(k % 2 == 0, 1, 0)[:, None] * np.array(even) + np.where(k % 2 == 1, 1, 0)[:, None] * np.array(odd)
    x = shape * (amp[:, 0] * np.exp(2j * math.pi * 900.0 * t) + amp[:, 1] * np.exp(-2j * math.pi * 900.0 * t))
    noise = 0.05 * (np.random.default_rng(1).standard_normal(n) + 1j * np.random.default_rng(2).standard_normal(n))
    return (x + noise)[None, :, None].astype(np.complex64)


@pytest.mark.parametrize("rate", [97.3, 151.7, 290.1])
def test_a_turn_is_doubled_and_a_lopsided_flash_train_is_not(rate):
    """Equal blades seen stronger on the approaching side leak their flash train into the
    approaching-minus-receding envelope by a few per cent of its power: read at their flash rate,
    not doubled. A tagged blade alternating sides makes the difference's line at the turn rate as
    strong as the sum's: the turn, doubled to the flash rate."""
    config = EXTRA_PRESETS["cw-sband"].config
    lopsided = flash.spectral_flash_rate(_two_sided_train(rate, (1.0, 0.7), (1.0, 0.7)), config, np.zeros(1))
    assert abs(lopsided.rate_hz[0] - rate) <= 0.005 * rate, lopsided.rate_hz[0]
    tagged = flash.spectral_flash_rate(_two_sided_train(rate, (1.0, 0.2), (0.2, 0.6)), config, np.zeros(1))
    assert abs(tagged.rate_hz[0] - rate) <= 0.005 * rate, tagged.rate_hz[0]


def test_equal_blades_are_read_at_their_flash_rate():
    """Every blade tagged alike on the S-band CW radar (training simulator): the flash rate, not
    twice it (seeds where the turn rule once doubled it)."""
    for seed in (10, 14, 17):
        rec, _ = simulate(Scene(profile=shipped_profiles()["m300"], range_m=400.0, snr_db=10.0, radial_speed_mps=0.0,
                                tagged_blades=8), EXTRA_PRESETS["cw-sband"], seed=seed)
        flown = 2.0 * float(np.mean(json.loads(rec.simulation)["truth"]["rotor_rates_hz"]))
        assert abs(extract(rec).features.flash_rate_hz - flown) <= 0.03 * flown, seed


@settings(max_examples=8, deadline=None)
@given(log10_scale=st.floats(-25, 25))
def test_long_dwell_estimates_ignore_the_iq_scale(log10_scale):
    """Envelope spectrum, rotors seen, detection and body line of a CW dwell do not depend on the
    IQ scale (the cube is scaled by a power of two first; only the peak amplitude moves)."""
    rec = _tagged_cw()
    base = extract(rec)
    scaled = extract(replace(rec, iq=rec.iq.astype(np.complex128) * 10.0 ** log10_scale))
    for name in ("flash_rate_hz", "rotor_rate_hz", "radial_velocity_mps", "detected", "flash_score"):
        a, b = getattr(base.features, name), getattr(scaled.features, name)
        assert b == pytest.approx(a, rel=1e-4, abs=1e-6), name
    assert scaled.physics["rotors_seen"] == base.physics["rotors_seen"]


@functools.cache
def _tagged_cw():
    from lab.accuracy import CONDITIONS, render_condition

    return render_condition(CONDITIONS["cw-hover-tagged"], "training", 3)[0]
