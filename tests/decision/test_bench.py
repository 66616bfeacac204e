"""`authn bench` machinery on a tiny run: categories, expected decisions, skipping, the front."""

from __future__ import annotations

from authn.bench import CATEGORIES, EXPECTED, run_decisions, summarise
from authn.pareto import Point, _mark_front


def test_decision_rows_cover_every_category() -> None:
    rows = run_decisions(("paper",), 3, seed=1)
    assert [r.category for r in rows] == list(CATEGORIES)
    by = {r.category: r for r in rows}
    assert by["unregistered"].radar_skipped == by["revoked"].radar_skipped == 3
    assert by["genuine"].radar_skipped == 0
    assert all(r.correct == r.n for r in rows if EXPECTED[r.category] == "reject")  # spoofs never pass
    assert set(summarise(rows)["paper"]) == set(CATEGORIES)


def test_pareto_front_marks_only_undominated_points() -> None:
    snrs = (0.0, 10.0)
    pts = [Point("fast-bad", 1.0, {0.0: 0.5, 10.0: 0.6}, 0.0), Point("slow-good", 5.0, {0.0: 0.99, 10.0: 1.0}, 0.0),
           Point("dominated", 6.0, {0.0: 0.9, 10.0: 0.9}, 0.0)]
    _mark_front(pts, snrs)
    assert [p.pareto for p in pts] == [True, True, False]
