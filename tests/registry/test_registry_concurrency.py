"""Several processes registering overlapping serials: no duplicates, no partial rows."""

from __future__ import annotations

from sqlalchemy import text

from registry.db import get_engine


def test_concurrent_registrations(db_url):
    from registry_workers import register_many, run_in_processes

    get_engine(db_url)  # migrate first: this test is about registrations
    serials = [f"1581F5FJD{n:011d}" for n in range(24)]
    # each process takes 12 serials, overlapping its neighbours by half
    chunks = [serials[6 * k:6 * k + 12] or serials[:12] for k in range(4)]
    chunks[3] = serials[18:] + serials[:6]
    results = run_in_processes(register_many, [(db_url, c) for c in chunks])
    assert sum(ok for ok, _ in results) == len(serials)
    assert sum(dup for _, dup in results) == 4 * 12 - len(serials)
    with get_engine(db_url).connect() as conn:
        rows = conn.execute(text("SELECT serial, model_slug, operator_id, status FROM identities")).all()
    assert sorted(r.serial for r in rows) == serials
    assert all(r.model_slug == "m300" and r.operator_id == "OP-1" and r.status == "active" for r in rows)
