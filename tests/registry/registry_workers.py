"""Functions run in spawned processes by the concurrency tests (must be importable)."""

from __future__ import annotations

import multiprocessing as mp


def _call(fn, args, barrier, results, i) -> None:
    try:
        results.put((i, fn(*args, barrier)))
    except BaseException as exc:  # reported to the parent test, not swallowed
        results.put((i, exc))


def run_in_processes(fn, arg_lists: list[tuple]) -> list:
    """Run fn(*args, barrier) in one spawned process per arg tuple, released together."""
    ctx = mp.get_context("spawn")
    barrier, results = ctx.Barrier(len(arg_lists)), ctx.Queue()
    procs = [ctx.Process(target=_call, args=(fn, a, barrier, results, i))
             for i, a in enumerate(arg_lists)]
    for p in procs:
        p.start()
    out = dict(results.get(timeout=120) for _ in procs)
    for p in procs:
        p.join(30)
    errors = [r for r in out.values() if isinstance(r, BaseException)]
    if errors:
        raise errors[0]
    return [out[i] for i in range(len(procs))]


def register_many(url: str, serials: list[str], barrier) -> tuple[int, int]:
    """Register each serial; returns (registered, refused as duplicates)."""
    from registry.db import session_scope
    from registry.errors import RegistryError
    from registry.store import NewIdentity, register_identity

    barrier.wait()
    ok = dup = 0
    for s in serials:
        try:
            with session_scope(url) as session:
                register_identity(session, NewIdentity(serial=s, model="m300", operator_id="OP-1"))
            ok += 1
        except RegistryError as exc:
            assert "already registered" in str(exc), str(exc)
            dup += 1
    return ok, dup


def first_use(url: str, barrier) -> str:
    """Open the database the way every command does (auto-migration on first use)."""
    from sqlalchemy import text

    from registry.db import get_engine

    barrier.wait()
    with get_engine(url).connect() as conn:
        return conn.execute(text("SELECT version_num FROM alembic_version")).scalar_one()
