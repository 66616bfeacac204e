"""The reach bench's parts (lab/bench/reach.py): a view that does not depend on the return's scale,
pairwise LLRs that are calibrated (near 0 where two classes cannot be told apart, large where they
can), and tracks walked by the check's own sequential test."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lab.bench.reach import dwell_view, pair_llr, scene_icc, walk_scenes

PRI_S = 44e-6


def _cube(seed: int) -> np.ndarray:
    """A body line plus a flash train at 120 Hz and noise: 600 chirps x 80 IF samples."""
    rng = np.random.default_rng(seed)
    t = np.arange(600)[:, None] * PRI_S
    k = np.arange(80)[None, :]
    body = np.exp(2j * np.pi * (0.2 * k + 900.0 * t))
    flash = (np.cos(np.pi * 120.0 * t) ** 40) * np.exp(2j * np.pi * (0.2 * k + rng.uniform(-9e3, 9e3, (600, 1)) * t))
    return (body + 3.0 * flash + 0.3 * (rng.standard_normal((600, 80)) + 1j * rng.standard_normal((600, 80))))


@settings(max_examples=20, deadline=None)
@given(st.floats(-9.0, 9.0), st.floats(0.0, 6.283), st.integers(0, 3))
def test_the_view_is_scale_invariant(log10_scale: float, phase: float, seed: int) -> None:
    cube = _cube(seed)
    scaled = cube * (10.0 ** log10_scale) * np.exp(1j * phase)
    np.testing.assert_allclose(dwell_view(scaled, PRI_S), dwell_view(cube, PRI_S), rtol=1e-3, atol=1e-3)


def test_the_view_of_an_empty_cube_is_finite() -> None:
    assert np.isfinite(dwell_view(np.zeros((600, 80), np.complex64), PRI_S)).all()


def _probabilities(sep: float, n: int = 400, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Probabilities of classes a and b from a score that separates them by `sep` standard deviations."""
    rng = np.random.default_rng(seed)
    y = np.array(["a", "b"] * (n // 2))
    score = np.where(y == "a", sep / 2, -sep / 2) + rng.standard_normal(n)
    pa = 1.0 / (1.0 + np.exp(-score))
    return np.column_stack([pa, 1.0 - pa]), y, np.arange(n) // 4  # scenes of 4 dwells


def test_pairwise_llrs_are_calibrated() -> None:
    p, y, g = _probabilities(0.0)
    llr, is_a = pair_llr(p, ["a", "b"], y, g, "a", "b")
    assert abs(llr[is_a].mean()) < 0.1 and abs(llr[~is_a].mean()) < 0.1  # no information: about 0
    p, y, g = _probabilities(4.0)
    llr, is_a = pair_llr(p, ["a", "b"], y, g, "a", "b")
    # two unit normals 4 apart: the true LLR is 4 x score, its mean under each class +-8 (KL)
    assert 6.5 < llr[is_a].mean() < 9.5 and -9.5 < llr[~is_a].mean() < -6.5


def test_tracks_walk_as_the_check_does() -> None:
    scenes = np.repeat(np.arange(5), 4)
    assert walk_scenes(np.full(20, 5.0), scenes, 0.2) == [("accept", 3)] * 5  # 4, 6.67, 8.57 nats
    assert walk_scenes(np.full(20, -5.0), scenes, 0.2) == [("reject", 2)] * 5
    # a mean dwell LLR under accept_nats x rho (6.9 x 0.2) never accepts, however long the track
    assert {d for d, _ in walk_scenes(np.full(20, 1.3), scenes, 0.2)} == {"inconclusive"}
    assert {d for d, _ in walk_scenes(np.full(20, 1.3), scenes, 0.1)} == {"accept"}


def test_the_scene_correlation_tells_repeated_bias_from_noise() -> None:
    rng = np.random.default_rng(1)
    scenes = np.repeat(np.arange(50), 5)
    assert abs(scene_icc(rng.standard_normal(250), scenes, 4.0)) < 0.15
    assert scene_icc(np.repeat(rng.standard_normal(50), 5) + 0.1 * rng.standard_normal(250), scenes, 4.0) > 0.9


def test_the_track_eer_follows_the_random_effects_model() -> None:
    """Dwells N(+-1, 1) around scene biases of variance 0.25: a 75-dwell mean is N(+-1, 0.25 + 1/75),
    an EER of Phi(-1 / 0.513) = 2.6 %; without scene biases the same dwells separate almost surely,
    and a scene bias alone (no dwell noise) is the floor however many dwells are averaged."""
    import math

    from lab.bench.reach import _eer_normal, track_eer

    rng = np.random.default_rng(3)
    scenes = np.repeat(np.arange(400), 6)
    is_a = scenes < 200
    bias = np.repeat(rng.normal(0.0, 0.5, 400), 6)
    llr = np.where(is_a, 1.0, -1.0) + bias + rng.standard_normal(scenes.size)
    want = 0.5 * math.erfc(1.0 / math.sqrt(0.25 + 1 / 75) / math.sqrt(2.0))
    assert track_eer(llr, is_a, scenes, 4.0) == pytest.approx(want, abs=0.012)
    no_bias = np.where(is_a, 1.0, -1.0) + rng.standard_normal(scenes.size)
    assert track_eer(no_bias, is_a, scenes, 4.0) < 1e-6
    assert _eer_normal(1.0, 0.5, -1.0, 0.5) == pytest.approx(0.5 * math.erfc(2.0 / math.sqrt(2.0)), rel=1e-6)
    # an 8-dwell track (what a site decides on) averages less of the dwell noise away
    want8 = 0.5 * math.erfc(1.0 / math.sqrt(0.25 + 1 / 8) / math.sqrt(2.0))
    assert track_eer(llr, is_a, scenes, 4.0, dwells=8) == pytest.approx(want8, abs=0.015)
    assert want8 > want + 0.02


def test_the_vector_without_the_envelope_drops_exactly_its_features() -> None:
    from lab.bench.reach import RenderedDwell, _without_envelope
    from signatures.dsp.feature_vector import ENVELOPE_FEATURES, FEATURE_NAMES

    names = sorted(FEATURE_NAMES)
    d = RenderedDwell("heldout", 10.0, "m300", 0, [float(i) for i in range(len(names))], [])
    kept = _without_envelope(d)
    assert len(kept) == len(FEATURE_NAMES) - len(ENVELOPE_FEATURES)
    assert [names[int(v)] for v in kept] == [n for n in names if n not in ENVELOPE_FEATURES]


def test_a_cache_of_another_feature_vector_is_refused_in_one_line(tmp_path, capsys) -> None:
    import json

    from lab.bench.reach import main

    cache = tmp_path / "dwells.json"
    cache.write_text(json.dumps([{"world": "heldout", "snr_db": 10.0, "flies": "m300", "scene": 0,
                                  "features": [0.0] * 34, "view": []}]))
    with pytest.raises(SystemExit) as exc:
        main(["--world", "heldout", "--snr", "10", "--cache", str(cache)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "holds another feature vector" in err and "delete it" in err


def test_a_track_of_no_dwells_is_refused_in_one_line(capsys) -> None:
    from lab.bench.reach import main

    with pytest.raises(SystemExit) as exc:
        main(["--track-dwells", "0"])
    assert exc.value.code == 2
    assert "--track-dwells 0" in capsys.readouterr().err.strip().splitlines()[-1]


def test_a_site_enrols_k_recordings_of_each_airframe_even_in_a_group() -> None:
    from lab.bench.reach import per_airframe

    airframes = np.array(["m300"] * 50 + ["m600"] * 40 + ["phantom4"] * 3)
    picked = per_airframe(np.arange(airframes.size), airframes, 30, np.random.default_rng(0))
    counts = {a: int(np.sum(airframes[picked] == a)) for a in ("m300", "m600", "phantom4")}
    assert counts == {"m300": 30, "m600": 30, "phantom4": 3}  # a group of two keeps 30 of each
    assert len(set(picked.tolist())) == picked.size


def _dwells(world: str, snr: float, shift: float, n: int = 40, seed: int = 0):
    """Dwells of two airframes whose first feature separates them by 2 + `shift` one way or the other."""
    from lab.bench.reach import RenderedDwell

    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        flies = ("m300", "phantom4")[i % 2]
        x = (1.0 if flies == "m300" else -1.0) + shift + 0.3 * rng.standard_normal(3)
        out.append(RenderedDwell(world, snr, flies, i // 4, x.tolist(), []))
    return out


def test_caches_are_read_in_order_the_first_holding_a_world_supplies_it(tmp_path) -> None:
    import json
    from dataclasses import asdict

    from lab.bench.reach import read_caches

    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps([asdict(d) for d in _dwells("heldout", 10.0, 0.0, 8)]))
    b.write_text(json.dumps([asdict(d) for d in _dwells("heldout", 10.0, 5.0, 6) + _dwells("randomised", 10.0, 0.0, 4)
                             + _dwells("randomised", 0.0, 0.0, 2)]))
    got = read_caches([str(a), str(b)], ["heldout", "randomised"], [10.0])
    assert [(d.world, d.snr_db) for d in got] == [("heldout", 10.0)] * 8 + [("randomised", 10.0)] * 4
    assert all(d.features[0] < 3.0 for d in got)  # b's shifted heldout dwells are not mixed in


def test_transfer_fits_on_a_union_of_worlds_and_scores_only_the_others(monkeypatch) -> None:
    import lab.bench.reach as reach

    monkeypatch.setattr(reach, "_layout", lambda ds, inputs, groups=None: (
        np.array([d.features for d in ds]), np.array([d.flies for d in ds]), np.array([d.scene for d in ds])))
    dwells = _dwells("training", 10.0, 0.0) + _dwells("randomised", 10.0, 0.0, seed=1) + _dwells("heldout", 10.0, 0.0,
                                                                                                  seed=2)
    rows = reach.transfer(dwells, "features", "training+randomised", track_dwells=8)
    assert {r.world for r in rows} == {"heldout"} and {r.fitted_on for r in rows} == {"training+randomised world"}
    assert len(rows) == 2 and all(r.track_eer < 0.05 for r in rows)  # the worlds agree: it transfers
    assert reach.transfer(dwells, "features", "training+bogus") == []  # a world it lacks: nothing to fit


def test_a_randomised_scene_draws_its_nuisances_once_for_all_its_dwells(monkeypatch) -> None:
    import lab.bench.reach as reach
    import lab.bench.track as track

    seen = []
    monkeypatch.setattr(track, "track_recordings", lambda scene, *a, world, **k: seen.append((scene, world)) or [])
    reach._render(("randomised", 10.0, 11, 0, "m300", 3, 5))
    reach._render(("randomised", 10.0, 11, 0, "m300", 3, 5))
    reach._render(("training", 10.0, 11, 0, "m300", 3, 5))
    (r1, w1), (r2, _), (plain, w3) = seen
    assert w1 == w3 == "training" and r1.nuisance is not None and plain.nuisance is None
    assert r1 == r2  # the same scene draws the same nuisances (seeded by the scene)
    assert r1.profile == plain.profile and r1.range_m == plain.range_m  # the track accuracy run's scene, randomised


def test_the_normal_eer_of_point_masses_is_finite() -> None:
    from lab.bench.reach import _eer_normal

    assert _eer_normal(4.0, 0.0, -4.0, 0.0) == pytest.approx(0.0, abs=1e-12)  # every LLR at the cap
    assert _eer_normal(1.0, 0.0, 1.0, 0.0) == pytest.approx(0.5, abs=1e-6)  # the same point: chance


def test_a_fit_world_not_rendered_is_refused_in_one_line(capsys) -> None:
    from lab.bench.reach import main

    with pytest.raises(SystemExit) as exc:
        main(["--world", "heldout", "--world", "training", "--transfer", "features",
              "--fit-world", "training+randomised"])
    assert exc.value.code == 2
    assert "--fit-world training+randomised: randomised" in capsys.readouterr().err.strip().splitlines()[-1]
