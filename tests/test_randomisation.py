"""Domain randomisation (`signatures.sim.scene.Nuisance`, `signatures.sim.sampling.NuisanceDistribution`):
neutral defaults, the physics of each knob, and sane cubes for any draw."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from signatures.features import extract
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.sim.sampling import NuisanceDistribution, SceneDistribution, sample_nuisance, sample_scene
from signatures.sim.scene import Nuisance, Scene
from signatures.sim.simulate import simulate

PAPER = get_preset("paper")
WIDE = get_preset("wide")
M300 = shipped_profiles()["m300"]


def _scene(**kw) -> Scene:
    base = dict(kind="uav", profile=M300, range_m=300.0, snr_db=20.0, clutter_db=5.0, elevation_deg=5.0)
    base.update(kw)
    return Scene(**base)


def test_default_nuisance_renders_the_plain_scene() -> None:
    plain, _ = simulate(_scene(), PAPER, seed=3)
    neutral, _ = simulate(_scene(nuisance=Nuisance()), PAPER, seed=3)
    np.testing.assert_array_equal(plain.iq, neutral.iq)


def test_rotor_rate_scale_moves_the_measured_flash_rate() -> None:
    """A rotor 12 % faster flashes 12 % faster: truth and the estimator both follow."""
    rates = []
    for scale in (1.0, 1.12):
        sc = _scene(snr_db=30.0, clutter_db=None, yaw_deg=0.0, rotor_rate_jitter=0.0,
                    nuisance=Nuisance(rotor_rate_scale=scale))
        rec, truth = simulate(sc, WIDE, seed=4)
        assert abs(truth.rotor_rate_hz - scale * M300.rotor_rate_hz) < 1e-9
        rates.append(extract(rec).features.flash_rate_hz)
    assert rates[0] > 0
    assert abs(rates[1] / rates[0] - 1.12) < 0.04


def test_adc_quantisation_leaves_at_most_2_to_the_bits_levels() -> None:
    rec, _ = simulate(_scene(nuisance=Nuisance(adc_bits=6)), PAPER, seed=5)
    assert len(np.unique(rec.iq.real)) <= 2 ** 6 + 1
    assert len(np.unique(rec.iq.imag)) <= 2 ** 6 + 1


def test_iq_imbalance_creates_a_mirror_image() -> None:
    """A gain/phase error between I and Q puts an image of the target at the mirrored beat frequency."""
    def image_ratio(nz: Nuisance) -> float:
        rec, _ = simulate(_scene(snr_db=None, clutter_db=None, nuisance=nz), PAPER, seed=6, range_offset_m=280.0)
        spec = np.mean(np.abs(np.fft.fft(rec.iq * np.hanning(rec.n_samples), axis=1)) ** 2, axis=0)
        k = int(np.argmax(spec))
        return float(spec[(-k) % spec.size] / spec[k])
    # expected image rejection of 10 % / 5 deg: (0.1**2 + 0.087**2) / 4 = 4.4e-3
    assert image_ratio(Nuisance()) < 1e-4
    assert image_ratio(Nuisance(iq_gain_imbalance=0.1, iq_phase_imbalance_deg=5.0)) > 2e-3


def test_acceleration_changes_the_phase_history_not_the_start() -> None:
    a, _ = simulate(_scene(snr_db=None, clutter_db=None), PAPER, seed=7, range_offset_m=280.0)
    b, _ = simulate(_scene(snr_db=None, clutter_db=None, nuisance=Nuisance(radial_accel_mps2=3.0)), PAPER, seed=7,
                    range_offset_m=280.0)
    np.testing.assert_allclose(a.iq[0], b.iq[0], atol=1e-4)  # float32 beat paths differ
    assert float(np.max(np.abs(a.iq[-1] - b.iq[-1]))) > 0.1


def test_draws_stay_within_their_spans() -> None:
    dist = NuisanceDistribution()
    rng = np.random.default_rng(0)
    for _ in range(200):
        nz, fields = sample_nuisance(rng, dist)
        assert dist.rotor_rate_scale[0] <= nz.rotor_rate_scale < dist.rotor_rate_scale[1]
        assert dist.body_scatterers[0] <= nz.body_scatterers <= dist.body_scatterers[1]
        assert nz.adc_bits in dist.adc_bits
        assert dist.rotor_rate_jitter[0] <= fields["rotor_rate_jitter"] < dist.rotor_rate_jitter[1]
        assert dist.blade_cone_deg[0] <= nz.blade_cone_deg < dist.blade_cone_deg[1]


def test_a_distribution_without_nuisance_draws_what_it_always_drew() -> None:
    dist = SceneDistribution(order=("range", "elevation", "speed", "snr"), range_m=(100, 900),
                             elevation_deg=(0, 40), hover_fraction=0.5, speed_mps=(1, 15), snr_db=(0, 20))
    a = sample_scene(np.random.default_rng(1), M300, dist)
    assert a.nuisance is None
    b = sample_scene(np.random.default_rng(1), M300, SceneDistribution(**{**dist.__dict__,
                                                                          "nuisance": NuisanceDistribution()}))
    assert b.nuisance is not None and (a.range_m, a.snr_db) == (b.range_m, b.snr_db)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), bird=st.booleans())
def test_any_draw_gives_a_finite_complex64_cube(seed: int, bird: bool) -> None:
    dist = SceneDistribution(order=("range", "elevation", "speed", "snr", "clutter"), range_m=(60, 1100),
                             elevation_deg=(-10, 60), hover_fraction=0.3, speed_mps=(0.5, 20), snr_db=(-10, 40),
                             clutter_band=(0.0, 0.5), clutter_db=(0, 20), nuisance=NuisanceDistribution())
    rng = np.random.default_rng(seed)
    sc = sample_scene(rng, "bird" if bird else M300, dist)
    rec, _ = simulate(sc, PAPER, seed=seed)
    assert rec.iq.dtype == np.complex64
    assert np.isfinite(rec.iq.view(np.float32)).all()
    assert np.isfinite(extract(rec).as_array()).all()


def _flash_peak_db(cone_deg: float, elevation_deg: float) -> float:
    """Peak over mean power of the target bins' fast-varying part (the blade flashes), target only."""
    sc = _scene(snr_db=None, clutter_db=None, elevation_deg=elevation_deg, yaw_deg=0.0, rotor_rate_jitter=0.0,
                attitude_wobble_deg=0.0, nuisance=Nuisance(blade_cone_deg=cone_deg))
    rec, _ = simulate(sc, WIDE, seed=11, range_offset_m=270.0)
    bins = np.fft.fft(rec.iq * np.hanning(rec.n_samples), axis=1)
    peak = int(np.argmax(np.mean(np.abs(bins) ** 2, axis=0)))
    slow = bins[:, peak - 1:peak + 2]
    fast = slow - np.mean(slow, axis=0)  # hovering: the body and hubs are the mean
    power = np.sum(np.abs(fast) ** 2, axis=1)
    return float(10 * np.log10(power.max() / power.mean()))


def test_coned_blades_flash_apart_off_the_rotor_plane() -> None:
    """Seen in the rotor plane a coned rotor's two blades still flash together; seen from 30 deg
    above it they pass broadside at different angles, so each flash holds one blade, not two."""
    assert abs(_flash_peak_db(4.0, 0.0) - _flash_peak_db(0.0, 0.0)) < 1.0
    assert _flash_peak_db(0.0, 30.0) - _flash_peak_db(4.0, 30.0) > 3.0  # 6 dB when the blades are equal
