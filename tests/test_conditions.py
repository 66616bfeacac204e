"""Test worlds for a real radar's conditions (issue 31; docs/signal-model.md "Test conditions"):
S-band CW returns and long dwells, hovering over strong static clutter, tagged (unequal) blades,
idling rotors, several targets in one dwell, in the training simulator and the held-out world,
and the scoring of `lab.accuracy.evaluate_condition`. Physics is checked on the raw signal, never
through the estimators."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pydantic import ValidationError

from lab import heldout
from lab.accuracy import CONDITIONS, DJI_QUAD, Estimate, evaluate_condition
from signatures.dsp import rd
from signatures.radar import get_preset
from signatures.sim.scene import MultiScene, Scene
from signatures.sim.simulate import simulate, simulate_many

CW = get_preset("cw-sband")


def _scene(**kw) -> Scene:
    base = dict(profile=DJI_QUAD, range_m=300.0, snr_db=None, rotor_rate_jitter=0.0, blade_to_body_db=-10.0)
    return Scene(**{**base, **kw})


@pytest.mark.parametrize("kw, match", [
    (dict(tagged_blades=9), "exceeds the airframe's 8 blades"),
    (dict(blade_weights=((1.0, 2.0),) * 3), "4 rotors x 2 blades"),
    (dict(blade_weights=((1.0, 2.0, 1.0),) * 4), "4 rotors x 2 blades"),
    (dict(blade_weights=((1.0, -2.0),) * 4), r"\[0, 100\]"),
    (dict(blade_weights=((1.0, float("nan")),) * 4), r"\[0, 100\]"),
    (dict(blade_weights=((0.0, 0.0),) * 4), "at least one blade"),
    (dict(blade_weights=((1.0, 2.0),) * 4, tagged_blades=1), "not both"),
    (dict(rotor_rate_hz=0.5), "greater than 1"),
    (dict(rotor_rate_hz=900.0), "less than or equal to 500"),
    (dict(tag_gain_db=-3.0), "greater than or equal to 0"),
    (dict(tag_layout="diagonal"), "'random' or 'spread'"),
    (dict(snr_db=10.0, clutter_db=20.0, clutter_to_signal_db=30.0), "not both"),
])
def test_condition_knobs_refuse_bad_input(kw: dict, match: str) -> None:
    with pytest.raises(ValidationError, match=match):
        _scene(**kw)


def test_knobs_belong_to_uav_scenes() -> None:
    with pytest.raises(ValidationError, match="UAV's rotors"):
        Scene(kind="bird", range_m=100.0, rotor_rate_hz=60.0)
    with pytest.raises(ValidationError, match="UAV's rotors"):
        Scene(kind="bird", range_m=100.0, tagged_blades=1)
    with pytest.raises(ValidationError, match="needs a target"):
        Scene(kind="none", clutter_to_signal_db=30.0)


def test_multi_scene_refuses_bad_input() -> None:
    drone = Scene(profile=DJI_QUAD, range_m=300.0, snr_db=10.0)
    with pytest.raises(ValidationError):
        MultiScene(targets=())
    with pytest.raises(ValidationError):
        MultiScene(targets=(drone,) * 9)
    with pytest.raises(ValidationError, match="snr_db sets"):
        MultiScene(targets=(drone, Scene(profile=DJI_QUAD, range_m=310.0, snr_db=None)))
    with pytest.raises(ValidationError, match="clutter is the scene's"):
        MultiScene(targets=(drone, Scene(profile=DJI_QUAD, range_m=310.0, snr_db=5.0, clutter_db=10.0)))
    with pytest.raises(ValidationError, match="not a target"):
        MultiScene(targets=(drone, Scene(kind="none")))
    with pytest.raises(ValueError, match="pulses"):
        CW.with_pulses(8)


def test_cw_preset_and_long_dwells() -> None:
    """3.3 GHz CW at PRI 200 us: 4096 pulses (0.82 s) and 50000 (10 s), one sample each, domain cw."""
    assert CW.domain == "cw" and CW.config.carrier_hz == 3.3e9 and CW.config.pri_s == 200e-6
    assert CW.n_samples == 1 and abs(CW.dwell_s - 0.8192) < 1e-9
    long = CW.with_pulses(50000)
    assert long.n_chirps == 50000 and abs(long.dwell_s - 10.0) < 1e-9 and long.name == "cw-sband-50000"
    scene = _scene(snr_db=10.0, clutter_to_signal_db=30.0, tagged_blades=2)
    for world in (simulate, heldout.simulate):
        rec, _ = world(scene, long, seed=1)
        assert rec.domain == "cw" and rec.iq.shape == (50000, 1) and rec.iq.dtype == np.complex64
        assert rec.config.range_offset_m == 0.0


def test_clutter_to_signal_sets_the_clutter_power() -> None:
    """Clutter 30 dB over the target, in both worlds: its power is 1000x the target's (unit) power."""
    from signatures.sim.simulate import render

    scene = _scene(snr_db=10.0, clutter_to_signal_db=30.0)
    comps = render(scene, CW.config, CW.n_chirps, 1, seed=2)
    parts = heldout.render(scene, CW.config, CW.n_chirps, 1, seed=2)
    for target, clutter in ((comps.target, comps.clutter), (parts.target, parts.clutter)):
        assert target is not None and clutter is not None
        ratio = np.mean(np.abs(clutter) ** 2) / np.mean(np.abs(target) ** 2)
        assert ratio == pytest.approx(1000.0, rel=0.01)


def _flash_lines(x: np.ndarray, pri_s: float, f: float) -> tuple[float, float]:
    """Power of the flash cadence at f and 2f, in dB over its median: the cadence is the power of the
    positive-Doppler half of a 32-pulse spectrogram (a tagged blade crosses that half once a turn)."""
    x = x - x.mean()
    frames = np.lib.stride_tricks.sliding_window_view(x, 32)[::4] * np.hanning(32)
    spec = np.abs(np.fft.fftshift(np.fft.fft(frames, axis=1), axes=1)) ** 2
    cadence = spec[:, 17:].sum(axis=1)
    cadence = cadence - cadence.mean()
    power = np.abs(np.fft.rfft(cadence * np.hanning(cadence.size))) ** 2
    freq = np.fft.rfftfreq(cadence.size, 4 * pri_s)

    def at(fq: float) -> float:
        k = int(np.argmin(np.abs(freq - fq)))
        return float(power[k - 2:k + 3].max())
    floor = float(np.median(power))
    return 10 * np.log10(at(f) / floor), 10 * np.log10(at(2 * f) / floor)


@pytest.mark.parametrize("rate", [161.0, 67.0])
def test_a_tagged_blade_puts_a_flash_line_at_the_mechanical_rate(rate: float) -> None:
    """Equal blades repeat their pattern twice a turn: no line at the rotor rate. One tag per rotor
    marks each turn: a line at the mechanical rate (flight 161 Hz and idle 67 Hz)."""
    pre = CW.with_pulses(16384)
    tagged, tr = simulate(_scene(rotor_rate_hz=rate, tagged_blades=4, tag_layout="spread"), pre, seed=3)
    equal, te = simulate(_scene(rotor_rate_hz=rate), pre, seed=3)
    assert tr.rotor_rate_hz == pytest.approx(rate) and tr.pattern_rates_hz == pytest.approx((rate,) * 4)
    assert te.pattern_rates_hz == pytest.approx((2 * rate,) * 4)
    f_tag, _ = _flash_lines(tagged.iq[:, 0].astype(np.complex128), pre.config.pri_s, rate)
    f_eq, f2_eq = _flash_lines(equal.iq[:, 0].astype(np.complex128), pre.config.pri_s, rate)
    assert f_tag > 60.0 and f2_eq > 60.0  # the lines stand far above the noise-free floor
    assert f_eq < f2_eq - 60.0  # equal blades: nothing at the rotor rate


def test_heldout_tags_mark_the_turn_too() -> None:
    """The held-out world (its own tape-strip tags, blades already +-1.5 dB unequal): tags raise the
    rotor-rate line of the cadence well above an untagged airframe's."""
    pre = CW.with_pulses(16384)
    lines = {}
    for tags in (0, 4):
        rec, truth = heldout.simulate(_scene(rotor_rate_hz=161.0, tagged_blades=tags, tag_layout="spread",
                                             tag_gain_db=12.0), pre, seed=4)
        f = truth.rotor_rate_hz
        lines[tags] = _flash_lines(rec.iq[:, 0].astype(np.complex128), pre.config.pri_s, f)[0]
        assert truth.airframe is not None
        assert truth.pattern_rate_hz == pytest.approx(f if tags else 2 * f, rel=0.07)
    assert lines[4] > lines[0] + 6.0 and lines[4] > 20.0, lines


def test_idle_rotors_and_hovering_truth() -> None:
    """rotor_rate_hz sets the rate flown (idle 67 Hz: the training jitter stays within 1.5 %, the
    held-out spread within 6 %); a hovering body's truth velocity is 0 and its Doppler line sits at 0."""
    scene = _scene(rotor_rate_hz=67.0, rotor_rate_jitter=0.005, snr_db=None)
    rec, truth = simulate(scene, CW, seed=5)
    assert truth.radial_speed_mps == 0.0 and all(abs(r / 67.0 - 1) <= 0.015 for r in truth.rotor_rates_hz)
    doc = json.loads(rec.simulation)["truth"]
    assert doc["radial_speed_mps"] == 0.0 and len(doc["rotor_rates_hz"]) == 4
    assert doc["rotor_rate_hz"] == pytest.approx(truth.rotor_rate_hz)
    spec = np.abs(np.fft.fft(rec.iq[:, 0])) ** 2
    assert int(np.argmax(spec)) == 0  # the body: zero Doppler
    rec_h, truth_h = heldout.simulate(scene, CW, seed=5)
    assert truth_h.radial_speed_mps == 0.0
    assert truth_h.airframe is not None and all(abs(r / 67.0 - 1) <= 0.07 for r in truth_h.airframe.rotor_rates_hz)
    assert json.loads(rec_h.simulation)["truth"]["pattern_rates_hz"]


def test_unit_weights_render_the_plain_cube() -> None:
    """Blade weights of 1 are no tags: the same cube and the same draws as a scene without them."""
    plain, _ = simulate(_scene(snr_db=10.0), CW, seed=6)
    ones, truth = simulate(_scene(snr_db=10.0, blade_weights=((1.0, 1.0),) * 4), CW, seed=6)
    assert np.array_equal(plain.iq, ones.iq) and truth.pattern_rates_hz == pytest.approx(
        tuple(2 * r for r in truth.rotor_rates_hz))


@pytest.mark.parametrize("world", [simulate_many, heldout.simulate_many])
def test_two_drones_and_a_bird_give_two_drone_detections_at_their_ranges(world) -> None:
    """Two drones (470 m, 505 m, opposite speeds) and a bird (490 m) in one `paper` dwell over
    clutter: a truth each, and the range profile (clutter removed) has CFAR hits at both drones, 10 dB
    over the floor; in the training world none over 6 m from every target (blades smear a drone over
    +-4 bins: range-Doppler coupling)."""
    multi = MultiScene(targets=(Scene(profile=DJI_QUAD, range_m=470.0, radial_speed_mps=3.0, snr_db=10.0),
                                Scene(profile=DJI_QUAD, range_m=505.0, radial_speed_mps=-4.0, snr_db=10.0),
                                Scene(kind="bird", range_m=490.0, radial_speed_mps=6.0, snr_db=0.0)),
                       clutter_db=20.0)
    pre = get_preset("paper")
    rec, truths = world(multi, pre, seed=7)
    assert [t.label for t in truths] == ["dji-quad", "dji-quad", "bird"]
    assert [t.range_m for t in truths] == [470.0, 505.0, 490.0]
    assert [t.radial_speed_mps for t in truths] == [3.0, -4.0, 6.0]
    assert len(json.loads(rec.simulation)["truths"]) == 3
    profile = rd.range_profile(rd.range_fft(rec.iq))
    hits, _ = rd.cfar(profile, rec.n_chirps)
    bins = rec.config.range_offset_m + np.arange(profile.size) * rec.config.range_bin_m(rec.n_samples)
    for r in (470.0, 505.0):
        near = np.abs(bins - r) <= 2.0
        assert hits[near].any(), f"no detection within 2 m of {r} m"
        assert profile[near].max() > 10 * np.median(profile)  # 10 dB over the floor
    if world is simulate_many:  # the held-out clutter sways, and what sways survives mean removal
        assert not hits[np.min(np.abs(bins[:, None] - np.array([470.0, 490.0, 505.0])[None, :]), axis=1) > 6.0].any()


def test_multi_scene_refuses_a_target_outside_the_gate() -> None:
    from signatures.errors import SignaturesError

    multi = MultiScene(targets=(Scene(profile=DJI_QUAD, range_m=300.0, snr_db=10.0),
                                Scene(profile=DJI_QUAD, range_m=600.0, snr_db=10.0)))
    with pytest.raises(SignaturesError, match="leaves the gate"):
        simulate_many(multi, get_preset("paper"), seed=0)


def _truth_estimate(factor: float):
    """An estimator that reads the truth from the file (x factor for the rate): scores the scoring."""
    def estimate(rec) -> Estimate:
        doc = json.loads(rec.simulation)["truth"]
        rates = doc["rotor_rates_hz"] if "rotor_rates_hz" in doc else doc["airframe"]["rotor_rates_hz"]
        return Estimate(True, factor * float(np.mean(rates)), 0.0, 4.0)
    return estimate


@pytest.mark.parametrize("world", ["training", "heldout"])
def test_condition_scoring_counts_what_it_claims(world: str) -> None:
    perfect = evaluate_condition("cw-hover-tagged", n=6, world=world, estimate=_truth_estimate(1.0))
    assert (perfect.detected, perfect.velocity_ok, perfect.rotor_ok, perfect.rotors_ok) == (1.0, 1.0, 1.0, 1.0)
    assert perfect.rotor_median_err < 1e-9
    flash = evaluate_condition("cw-idle-tagged", n=6, world=world, estimate=_truth_estimate(2.0))
    assert flash.rotor_ok == 0.0 and flash.at_double == 1.0 and flash.at_half == 0.0
    assert set(CONDITIONS) >= {"cw-hover-tagged", "cw-hover-tagged-10s", "cw-idle-tagged"}


def test_condition_scenes_are_reproducible_and_in_band() -> None:
    cond = CONDITIONS["cw-idle-tagged"]
    a = [cond.scene(np.random.default_rng([i, 31])) for i in range(20)]
    b = [cond.scene(np.random.default_rng([i, 31])) for i in range(20)]
    assert [s for s, _ in a] == [s for s, _ in b]
    assert all(63.0 <= s.rotor_rate_hz <= 71.0 and 1 <= s.tagged_blades <= 8 and s.hovering for s, _ in a)
    assert {p.config.carrier_hz for _, p in a} <= {3.30e9, 3.35e9, 3.40e9}


def test_the_paper_spread_condition_spreads_the_rotors_and_nothing_else() -> None:
    """paper-hover-spread is paper-hover with each rotor's rate drawn 2-4 % (std) off the common one:
    the training simulator flies its rotors that far apart (truth), the control's 0.5 %."""
    spread, control = CONDITIONS["paper-hover-spread"], CONDITIONS["paper-hover"]

    def rates_apart(cond, seed: int) -> float:
        scene, pre, sim_seed = cond.draw(seed)
        _, truth = simulate(scene, pre, seed=sim_seed)
        r = np.asarray(truth.rotor_rates_hz)
        return float((r.max() - r.min()) / r.mean())

    for seed in range(6):
        (s, ps, _), (c, pc, _) = spread.draw(seed), control.draw(seed)
        assert 0.02 <= s.rotor_rate_jitter <= 0.04 and c.rotor_rate_jitter == 0.005
        assert s.model_copy(update={"rotor_rate_jitter": 0.005}) == c and ps == pc
        assert ps.name == "paper" and s.hovering and s.tagged_blades == 0 and s.profile.slug == "phantom4"
    assert np.median([rates_apart(spread, i) for i in range(12)]) > 3 * np.median([rates_apart(control, i)
                                                                                   for i in range(12)])
