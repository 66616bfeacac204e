"""The long-dwell rotor count (`signatures.dsp.rotor_lines`): noise makes no rotor, each rotor that
stands above the noise is one line, and the count does not depend on the envelope's scale; the
extraction marks it a lower bound on long dwells only; `lab.rotor_lines`'s oracle bound."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from signatures.dsp.rotor_lines import searched_slopes, visible_rotors

PRF = 5000.0


def _noise(n: int, rng: np.random.Generator) -> np.ndarray:
    """A power envelope of complex Gaussian noise in two halves (what `flash_envelope` sums)."""
    z = rng.standard_normal((2, n)) + 1j * rng.standard_normal((2, n))
    return (np.abs(z) ** 2).sum(axis=0)


def _rotors(n: int, flash_hz: float, offsets: list[float], amplitude: float, rng: np.random.Generator) -> np.ndarray:
    """Noise plus one flash train per rotor: Gaussian flashes 6 % of a period wide, each rotor at its
    own rate (flash_hz x (1 + offset)) and phase."""
    t = np.arange(n) / PRF
    out = _noise(n, rng)
    for off in offsets:
        phase = ((t * flash_hz * (1.0 + off)) + rng.uniform()) % 1.0
        dist = np.minimum(phase, 1.0 - phase)
        out += amplitude * np.exp(-0.5 * (dist / 0.06) ** 2)
    return out


def test_noise_alone_makes_no_rotor() -> None:
    rng = np.random.default_rng(0)
    for n in (4096, 50_000):
        for flash_hz in (130.0, 330.0):
            for _ in range(3):
                assert visible_rotors(_noise(n, rng), flash_hz / PRF) == []


def test_each_rotor_above_the_noise_is_one_line() -> None:
    rng = np.random.default_rng(1)
    offsets = [0.0, 0.004, -0.007, 0.011]
    for k in range(1, 5):
        lines = visible_rotors(_rotors(4096, 320.0, offsets[:k], 4.0, rng), 320.0 / PRF)
        assert len(lines) == k
        assert all(line.z >= lines[-1].z for line in lines)  # strongest first


def _crossings(n: int, flash_hz: float, fake: float, weak: float, rng: np.random.Generator) -> np.ndarray:
    """Noise, two rotors (4.0, rates flash_hz and +1 %) and a third train at -0.6 %: `weak` all
    along, plus `fake` only where its phase lies within 1.5 phase bins of the others' (where
    flashes coincide and interfere: what one rotor's subtraction leaves at a crossing)."""
    t = np.arange(n) / PRF
    bins = round(PRF / flash_hz)
    out = _noise(n, rng)
    phases = [(t * flash_hz * (1.0 + off) + rng.uniform()) % 1.0 for off in (0.0, 0.01, -0.006)]

    def flash(phase: np.ndarray, width: float) -> np.ndarray:
        dist = np.minimum(phase, 1.0 - phase)
        return np.exp(-0.5 * (dist / width) ** 2)

    out += 4.0 * (flash(phases[0], 0.06) + flash(phases[1], 0.06)) + weak * flash(phases[2], 0.06)
    near = np.zeros(n, dtype=bool)
    for p in phases[:2]:
        near |= np.abs((phases[2] - p + 0.5) % 1.0 - 0.5) < 1.5 / bins
    return out + fake * flash(phases[2], 0.02) * near


def test_what_crossings_leave_is_no_rotor_but_a_weak_rotor_through_them_is() -> None:
    """A 10 s dwell: a train that flashes only where it crosses two rotors' flashes adds up over
    the dwell to a line above the search's threshold (the count before read 3 rotors), but where
    it is clear of the counted lines it has nothing: 2 rotors. A weak third rotor (z 6-8, just over
    the threshold) that crosses them as often flashes everywhere, and is counted."""
    for seed in range(4):
        rng = np.random.default_rng(10 + seed)
        assert len(visible_rotors(_crossings(50_000, 130.0, 8.0, 0.0, rng), 130.0 / PRF)) == 2
        rng = np.random.default_rng(20 + seed)
        assert len(visible_rotors(_crossings(50_000, 130.0, 0.0, 0.8, rng), 130.0 / PRF)) == 3


def test_a_simulated_quad_whose_crossings_made_two_more_rotors_is_four(monkeypatch) -> None:
    """Scene 9 of cw-idle-tagged-10s (our simulator): its four rotors' lines cross tens of times over
    the 10 s; without the clear-window test two lines drawn through the crossings read 6 rotors, with
    it the count reads the 4."""
    import math

    import signatures.dsp.rotor_lines as rl
    from lab.accuracy import CONDITIONS, render_condition
    from signatures.features import extract

    rec, _, _, _, rotors = render_condition(CONDITIONS["cw-idle-tagged-10s"], "training", 9)
    assert rotors == 4 and extract(rec).physics["rotors_seen"] == 4.0
    monkeypatch.setattr(rl, "clear_z", lambda *a, **k: (math.inf, 10**6))  # every line clear of the others
    assert extract(rec).physics["rotors_seen"] == 6.0


def test_a_rotor_under_the_noise_is_not_seen() -> None:
    rng = np.random.default_rng(2)
    assert visible_rotors(_rotors(4096, 320.0, [0.0, 0.005], 0.002, rng), 320.0 / PRF) == []


def test_no_rate_or_too_short_a_dwell_sees_nothing() -> None:
    rng = np.random.default_rng(3)
    assert visible_rotors(_noise(4096, rng), 0.0) == []
    assert visible_rotors(_noise(100, rng), 320.0 / PRF) == []


@settings(max_examples=20, deadline=None)
@given(st.integers(min_value=-60, max_value=60))
def test_the_count_does_not_depend_on_the_envelope_scale(log2_scale: int) -> None:
    env = _rotors(4096, 320.0, [0.0, 0.006, -0.009], 4.0, np.random.default_rng(4))
    base = visible_rotors(env, 320.0 / PRF)
    scaled = visible_rotors(env * 2.0 ** log2_scale, 320.0 / PRF)
    assert [(line.slope, line.phase) for line in scaled] == [(line.slope, line.phase) for line in base]
    assert len(base) == 3


def test_the_oracle_sees_each_tagged_rotor_alone_and_restores_the_simulator() -> None:
    """Scene 37 of cw-hover-tagged (our simulator, 10 dB) tags all four rotors: each, rendered alone
    and folded at its true rate, stands far above the noise; the simulator is itself again after."""
    import signatures.sim.simulate as sim
    from lab.accuracy import CONDITIONS
    from lab.rotor_lines import rotors_alone

    before = sim._uav_amplitudes
    rotors = rotors_alone(CONDITIONS["cw-hover-tagged"], 37)
    assert sim._uav_amplitudes is before
    assert [(v, t) for v, t, _ in rotors] == [(True, True)] * 4
    assert min(z for _, _, z in rotors) > 8.0


def test_the_searching_oracle_pays_the_counts_threshold() -> None:
    """`search=True`: the same z per rotor against the count's Bonferroni threshold over its
    searched rate offsets too (`searched_slopes`). Scene 1 of cw-hover-tagged: a rotor at z 3.98
    clears the phase bins' threshold alone, not the search's (~4.9 for that image)."""
    from lab.accuracy import CONDITIONS
    from lab.rotor_lines import rotors_alone

    plain = rotors_alone(CONDITIONS["cw-hover-tagged"], 1)
    searched = rotors_alone(CONDITIONS["cw-hover-tagged"], 1, search=True)
    assert [z for _, _, z in plain] == [z for _, _, z in searched]
    assert [v for v, _, _ in plain] == [True] * 4
    assert [v for v, _, _ in searched] == [True, True, True, False]
    assert searched_slopes(31, 33).size > 400  # rows x bins of a 0.82 s tagged hover: ~490 rate offsets


def test_a_long_dwell_marks_its_count_a_lower_bound_and_a_short_one_does_not() -> None:
    from signatures.features import extract
    from signatures.radar import EXTRA_PRESETS, get_preset
    from signatures.sim.scene import Scene
    from signatures.sim.simulate import simulate

    from lab.accuracy import DJI_QUAD

    scene = dict(profile=DJI_QUAD, range_m=300.0, radial_speed_mps=0.0, snr_db=10.0, tagged_blades=4, tag_gain_db=12.0)
    long_rec, _ = simulate(Scene(**scene), EXTRA_PRESETS["cw-sband"], seed=3)
    physics = extract(long_rec).physics
    assert physics["rotors_lower_bound"] == 1.0
    assert 1.0 <= physics["rotors_seen"] <= 5.0 and physics["rotors_seen"] == int(physics["rotors_seen"])
    short = Scene(profile=DJI_QUAD, range_m=300.0, radial_speed_mps=0.0, snr_db=10.0)
    short_rec, _ = simulate(short, get_preset("paper"), seed=3)
    assert "rotors_lower_bound" not in extract(short_rec).physics


def test_the_oracle_refuses_no_scenes_in_one_line(capsys) -> None:
    from lab.rotor_lines import main

    with pytest.raises(SystemExit) as exc:
        main(["--condition", "cw-hover-tagged", "--n", "0"])
    assert exc.value.code == 2
    assert "--n 0: at least 1" in capsys.readouterr().err.strip().splitlines()[-1]
