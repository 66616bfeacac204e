"""`authn bench` machinery on a tiny run: categories, expected decisions, skipping, the front."""

from __future__ import annotations

import pytest

from lab.bench.decisions import CATEGORIES, DRIP_REASONS, EXPECTED, drip_cost, run_decisions, summarise
from lab.bench.pareto import Point, _mark_front, near_floor
from tests.lab_plugin import needs_lab


def test_decision_rows_cover_every_category() -> None:
    rows = run_decisions(("paper",), 3, seed=1)
    assert [r.category for r in rows] == list(CATEGORIES)
    assert CATEGORIES[:5] == ("genuine", "type_spoof", "position_spoof", "unregistered", "revoked")
    assert [c for c in CATEGORIES if EXPECTED[c] == "accept"] == ["genuine", "drip_genuine"]
    by = {r.category: r for r in rows}
    assert by["unregistered"].radar_skipped == by["revoked"].radar_skipped == 3
    assert by["genuine"].radar_skipped == by["drip_genuine"].radar_skipped == 0
    assert all(r.correct == r.n for r in rows if EXPECTED[r.category] == "reject")  # spoofs never pass
    # DRIP rejections: each with its own reason, decided before the radar
    assert set(DRIP_REASONS) == {"drip_unsigned", "drip_forged", "drip_replayed"}
    assert all(by[c].reason_missing == 0 and by[c].radar_skipped == 3 for c in DRIP_REASONS)
    assert all(len(r.auth_ms) == r.n for r in rows)
    summary = summarise(rows)["paper"]
    assert set(summary) == set(CATEGORIES)
    assert summary["drip_forged"]["reason_missing"] == 0 and "reason_missing" not in summary["genuine"]
    for r in rows:  # every wrong decision is counted once by reason and once by (flown -> claimed) pair
        assert sum(r.wrong_pairs.values()) == sum(r.wrong_reasons.values()) == r.n - r.correct
        assert summary[r.category]["wrong_pairs"] == r.wrong_pairs
    cost = drip_cost(rows)["paper"]
    assert (cost["signed_valid_n"], cost["signed_rejected_n"], cost["unsigned_n"]) == (3, 6, 18)
    assert cost["signed_valid_ms"] > cost["unsigned_ms"] > 0  # verifying costs more than finding nothing to verify


def test_claim_scenes_are_pinned() -> None:
    """The benchmark's claim scenes for a seed do not move (published figures were drawn with them)."""
    import numpy as np
    import pytest

    from lab.bench.decisions import random_scene

    rng = np.random.default_rng(0)
    pinned = [("m600", 77.1887409, 32.5308096, 1.57362934, 28.2551115, 14.5899312, 195.704997),
              ("m300", 62.8480402, 34.2961711, -12.4219498, 10.6717115, 3.51311241, 310.744412),
              ("phantom4", 89.452458, 4.97133106, -6.9176211, 23.4124883, 12.3077022, 138.12392)]
    for slug, *want in pinned:
        sc, az = random_scene(rng, slug, (10.0, 30.0))
        got = (sc.range_m, sc.elevation_deg, sc.radial_speed_mps, sc.snr_db, sc.clutter_db, az)
        assert sc.profile.slug == slug and got == pytest.approx(tuple(want), rel=1e-8)


def test_pareto_front_marks_only_undominated_points() -> None:
    snrs = (0.0, 10.0)
    pts = [Point("fast-bad", 1.0, {0.0: 0.5, 10.0: 0.6}, 0.0), Point("slow-good", 5.0, {0.0: 0.99, 10.0: 1.0}, 0.0),
           Point("dominated", 6.0, {0.0: 0.9, 10.0: 0.9}, 0.0)]
    _mark_front(pts, snrs)
    assert [p.pareto for p in pts] == [True, True, False]


def test_near_floor_needs_the_front_the_time_and_the_accuracy() -> None:
    snrs = (0.0, 10.0)
    pts = [Point("fast-bad", 1.0, {0.0: 0.5, 10.0: 0.6}, 0.0), Point("mid-good", 2.5, {0.0: 0.9, 10.0: 0.96}, 0.0),
           Point("slow-best", 5.0, {0.0: 0.99, 10.0: 1.0}, 0.0), Point("dominated", 2.9, {0.0: 0.8, 10.0: 0.95}, 0.0)]
    _mark_front(pts, snrs)
    assert [p.name for p in near_floor(pts, floor_ms=1.0)] == ["mid-good"]  # 5.0 ms is over 3x; 1.0 ms too weak
    assert [p.name for p in near_floor(pts, floor_ms=2.0)] == ["mid-good", "slow-best"]


def test_cold_times_run_real_processes(tmp_path) -> None:
    """One round of the cold-start measurement: every process runs to the end (a failing
    first-check script raises), and the ratios are computed from the medians."""
    from datetime import datetime, timezone

    from lab.bench.decisions import bench_serial, cold_times, random_scene, register_identities
    from authn.scenario import Broadcast, simulate_flight
    import numpy as np
    from signatures.radar import get_preset
    from signatures.recording import write_recording

    db = f"sqlite:///{tmp_path / 'cold.sqlite3'}"
    register_identities(db)
    scene, az = random_scene(np.random.default_rng(0), "m300", (20.0, 20.0))
    rec, _ = simulate_flight(scene, get_preset("paper"), 0, Broadcast(serial=bench_serial("m300")), azimuth_deg=az,
                             start_time=datetime.now(timezone.utc))
    t = cold_times(write_recording(rec, tmp_path / "r.h5"), bench_serial("m300"), db, repeats=1)
    assert all(v > 0 and np.isfinite(v) for v in t.values())
    assert t["cold_vs_import_numpy"] == t["cold_process_ms"] / t["import_numpy_ms"]


@pytest.mark.slow  # ~14 s
def test_pareto_grid_runs_every_configuration_on_one_set() -> None:
    """A tiny grid: every configuration (shipped bundle and retrained RFs) gets a positive
    time, scores in [0, 1] and the front is not empty."""
    from lab.bench.pareto import CONFIGS, RETRAINED, run

    pts = run("paper", snrs=(20.0,), per_class=1, seed=3, n_train=60)
    names = [p.name for p in pts]
    assert set(names) >= {name for name, _, cmode in CONFIGS if cmode not in ("cnn", "cascade-always")}
    assert set(names) >= {r[0] for r in RETRAINED}
    assert all(p.ms_per_return > 0 and 0.0 <= p.f1_by_snr[20.0] <= 1.0 and 0.0 <= p.far <= 1.0 for p in pts)
    assert any(p.pareto for p in pts)
    default = next(p for p in pts if p.name.endswith("(default)"))
    assert default.f1_by_snr[20.0] >= 0.8  # 5 returns at 20 dB: the shipped ensemble gets (almost) all


@needs_lab
@pytest.mark.slow  # ~80 s: `authn bench --quick` end to end
def test_bench_quick_cli_writes_the_report_and_the_plot(tmp_path, capsys, monkeypatch) -> None:
    """`authn bench --quick` end to end (latency skipped: it spawns processes): the JSON report has
    every section, and the error-versus-time PNG is written."""
    import json

    from authn.cli import main

    monkeypatch.setenv("AUTHN_CACHE_DIR", str(tmp_path / "cache"))
    assert main(["bench", "--quick", "--no-latency", "--json", "--plot", str(tmp_path / "fig")]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc) >= {"decisions", "stages", "fft_floor", "pareto", "near_fft_floor", "throughput_per_s"}
    assert doc["decisions"]["paper"]["unregistered"]["radar_skipped_rate"] == 1.0
    assert doc["decisions"]["paper"]["drip_forged"]["correct_rate"] == 1.0
    assert doc["drip_verification_ms"]["paper"]["signed_valid_n"] == 12
    assert {p["name"] for p in doc["pareto"]["paper"]} >= {"gated + ensemble (default)", "full cube + ensemble"}
    assert (tmp_path / "fig" / "error-vs-time-paper.png").stat().st_size > 10_000


def test_batch_curve_times_every_size_interleaved_beside_the_floor() -> None:
    """`authn bench --batch`: one median per size and the floor over the same rounds (at least 3)."""
    from lab.bench.batch import curve

    c = curve("paper", (1, 8), distinct=5, seed=1, budget_s=0.0)
    assert c["rounds"] == 3
    assert set(c["ms_per_return"]) == set(c["x_floor"]) == {"single", "1", "8"}
    assert c["fft_floor_ms"] > 0 and all(v > 0 for v in c["ms_per_return"].values())
    assert c["x_floor"]["8"] == c["ms_per_return"]["8"] / c["fft_floor_ms"]
    # every size runs the same returns (each at least once), not a small batch of the first few
    assert c["returns_timed"] == {"single": 5, "1": 5, "8": 8}
