"""The audit log and the registry over HTTP. Audit reads go through the check path's
DB-API connection (on the checker's thread); registry writes through the registry's
validated store, each followed by an audit entry naming the acting key."""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, HTTPException, Path, Query, Request
from pydantic import BaseModel, ConfigDict, Field, field_validator

from authn.service.auth import Caller
from authn.service.deps import require, runtime

router = APIRouter(prefix="/v1")
_AUTH: dict[int | str, dict[str, Any]] = {401: {"description": "no valid API key"},
                                          403: {"description": "role may not do this"}}
_SERIAL = r"^[\x21-\x7e]{1,64}$"


def _entry_json(e: Any) -> dict[str, Any]:
    return {"seq": e.seq, "created_at": e.created_at.isoformat(), "kind": e.kind, "serial": e.serial,
            "decision": e.decision, "payload": e.payload, "prev_hash": e.prev_hash, "entry_hash": e.entry_hash}


# --- audit ------------------------------------------------------------------------------

@router.get("/audit", tags=["audit"], responses=_AUTH)
async def audit_list(request: Request, after: Annotated[int, Query(ge=0, le=2**62)] = 0,
                     limit: Annotated[int, Query(ge=1, le=500)] = 100,
                     decision: Literal["accept", "reject", "inconclusive"] | None = None,
                     serial: Annotated[str | None, Query(max_length=64)] = None,
                     _caller: Caller = Depends(require("read_audit"))) -> dict[str, Any]:
    """Entries with seq > `after`, oldest first; `next_after` pages on (null at the end)."""
    from authn.audit import get_entry

    rt = runtime(request)
    where, params = ["seq > :after"], {"after": after, "limit": limit}
    for column, value in (("decision", decision), ("serial", serial)):
        if value is not None:
            where.append(f"{column} = :{column}")
            params[column] = value

    def page() -> list[Any]:
        db = rt.checker.db
        seqs = db.fetch(f"SELECT seq FROM audit_log WHERE {' AND '.join(where)} ORDER BY seq LIMIT :limit", params)
        return [get_entry(db, int(s)) for (s,) in seqs]

    entries = await rt.run(page)
    return {"entries": [_entry_json(e) for e in entries],
            "next_after": entries[-1].seq if len(entries) == limit else None}


@router.get("/audit:verify", tags=["audit"], responses=_AUTH)
async def audit_verify(request: Request, _caller: Caller = Depends(require("read_audit"))) -> dict[str, Any]:
    """Recompute the chain and Merkle tree; check them against every signed tree head known
    (as `authn audit verify`). `ok` false names the first bad entry."""
    from authn.audit import accepted_keys, known_heads, newest, verify
    from authn.audit.logkey import LogKey, key_path, load_retired_keys

    rt = runtime(request)

    def run() -> dict[str, Any]:
        db = rt.checker.db
        heads = known_heads(db)
        key = LogKey.load(None).public_key if heads or key_path(None).exists() else None
        retired = load_retired_keys(key_path(None))
        keys = accepted_keys(heads, key, retired) if key is not None else []
        forged = [h for h in heads if not any(h.sth.verify_signature(k) for k in keys)]
        if forged:
            h = min(forged, key=lambda h: h.sth.tree_size)
            return {"ok": False, "size": None, "first_bad_seq": None,
                    "problem": f"tree head of size {h.sth.tree_size} ({h.source}) is not signed by the log key"}
        report = verify(db, heads, public_key=key, retired=retired, require_signed_to_end=True)
        best = newest(heads)
        return {"ok": report.ok, "size": report.size, "head": report.head, "root": report.root,
                "first_bad_seq": report.first_bad_seq, "problem": report.problem,
                "newest_signed_size": best.sth.tree_size if best else None, "unsigned": report.unsigned}

    return await rt.run(run)


@router.post("/audit:checkpoint", tags=["audit"], responses=_AUTH)
async def audit_checkpoint(request: Request, _caller: Caller = Depends(require("checkpoint"))) -> dict[str, Any]:
    """Verify the log, then sign its head (authn-checkpoint/1: a C2SP checkpoint), as `authn audit checkpoint`."""
    import json

    from authn.audit import checkpoint

    rt = runtime(request)
    sth = await rt.run(lambda: checkpoint(rt.checker.db))
    return json.loads(sth.to_json())


@router.get("/audit/{seq}", tags=["audit"], responses={**_AUTH, 404: {"description": "no such entry"}})
async def audit_get(request: Request, seq: Annotated[int, Path(ge=1, le=2**62)],
                    _caller: Caller = Depends(require("read_audit"))) -> dict[str, Any]:
    """One entry in full (evidence, digests, hashes)."""
    from authn.audit import get_entry

    rt = runtime(request)
    entry = await rt.run(lambda: get_entry(rt.checker.db, seq))
    if entry is None:
        raise HTTPException(404, f"no audit entry {seq}")
    return _entry_json(entry)


# --- registry -----------------------------------------------------------------------------

class IdentityIn(BaseModel):
    """A registration (the fields of `authn register`); public_key is 64 hex digits."""

    model_config = ConfigDict(extra="forbid")

    serial: str = Field(min_length=1, max_length=64)
    model: str = Field(min_length=1, max_length=32)
    id_type: Literal["serial", "caa_registration", "utm_uuid", "specific_session"] = "serial"
    operator_id: str | None = Field(default=None, max_length=20)
    public_key: str | None = Field(default=None, max_length=64)
    valid_from: datetime | None = None
    valid_until: datetime | None = None
    notes: str | None = Field(default=None, max_length=2000)

    @field_validator("valid_from", "valid_until")
    @classmethod
    def _in_range(cls, v: datetime | None) -> datetime | None:
        """A time whose UTC instant Python cannot hold (0001-01-01T00:00:00+23:59) is a 422 here,
        not an OverflowError later."""
        from datetime import timezone

        from core.parsing import in_utc_range

        if v is not None and not in_utc_range(v if v.tzinfo else v.replace(tzinfo=timezone.utc)):
            raise ValueError("out of range (UTC times from 0001-01-02 to 9999-12-30)")
        return v


class RevokeIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    reason: str | None = Field(default=None, max_length=500)


def _record_json(rec: Any) -> dict[str, Any]:
    return rec.to_dict(json=True)


def _audit_change(rt: Any, caller: Caller, action: str, serial: str, detail: dict[str, Any]) -> None:
    """The registry change as an audit entry naming the acting key (kind 'registry')."""
    from authn.audit import AuditLog

    AuditLog(rt.checker.db).record_registry_change(serial, action, caller.key_id, caller.role, detail)


async def _audited_write(rt: Any, caller: Caller, action: str, serial: str, detail: dict[str, Any],
                         write: Callable[[], Any]) -> Any:
    """Write-ahead: the change's audit entry commits before the change, so no change is ever
    unaudited (the registry and the log are two transactions). A change that then fails is
    followed by an `<action>-failed` entry with the one-line reason."""
    from starlette.concurrency import run_in_threadpool

    from core.errors import describe

    await rt.run(lambda: _audit_change(rt, caller, action, serial, detail))
    try:
        return await run_in_threadpool(write)
    except Exception as exc:
        reason = describe(exc) if not isinstance(exc, HTTPException) else str(exc.detail)
        await rt.run(lambda: _audit_change(rt, caller, f"{action}-failed", serial, {"error": reason}))
        raise


@router.get("/identities", tags=["registry"], responses=_AUTH)
def identities_list(request: Request, status: Literal["active", "revoked"] | None = None,
                    _caller: Caller = Depends(require("read_registry"))) -> list[dict[str, Any]]:
    """Registered identities, by serial."""
    from registry.dbapi import transaction
    from registry.store import list_identities

    with transaction(runtime(request).settings.db_url) as s:
        return [_record_json(r) for r in list_identities(s, status)]


@router.post("/identities", tags=["registry"], status_code=201,
             responses={**_AUTH, 400: {"description": "invalid or duplicate identity"}})
async def identities_register(request: Request, body: IdentityIn,
                              caller: Caller = Depends(require("write_registry"))) -> dict[str, Any]:
    """Register an identity (admins); the change is audited with the acting key's id."""
    from core.checked import Invalid
    from core.errors import AuthnError
    from registry.dbapi import transaction
    from registry.store import NewIdentity, describe_validation_error, register_identity

    rt = runtime(request)
    try:
        new = NewIdentity(**body.model_dump(exclude_none=True))
    except Invalid as exc:
        raise AuthnError(describe_validation_error(exc)) from None

    def write() -> Any:
        with transaction(rt.settings.db_url) as s:
            return register_identity(s, new)

    rec = await _audited_write(rt, caller, "register", new.serial, {"model": new.model}, write)
    return _record_json(rec)


@router.get("/identities/{serial}", tags=["registry"], responses={**_AUTH, 404: {"description": "not registered"}})
def identities_get(request: Request, serial: Annotated[str, Path(pattern=_SERIAL)],
                   _caller: Caller = Depends(require("read_registry"))) -> dict[str, Any]:
    """One identity with its declared airframe."""
    from registry.dbapi import transaction
    from registry.store import get_identity

    with transaction(runtime(request).settings.db_url) as s:
        rec = get_identity(s, serial)
    if rec is None:
        raise HTTPException(404, f"serial {serial}: not registered")
    return _record_json(rec)


@router.post("/identities/{serial}:revoke", tags=["registry"],
             responses={**_AUTH, 404: {"description": "not registered"}, 400: {"description": "already revoked"}})
async def identities_revoke(request: Request, serial: Annotated[str, Path(pattern=_SERIAL)],
                            body: RevokeIn | None = None,
                            caller: Caller = Depends(require("write_registry"))) -> dict[str, Any]:
    """Revoke an identity (admins); kept for the audit trail, never deleted; audited."""
    from registry.dbapi import transaction
    from registry.store import get_identity, revoke_identity

    rt = runtime(request)
    reason = body.reason if body else None

    def write() -> Any:
        with transaction(rt.settings.db_url) as s:
            if get_identity(s, serial) is None:
                raise HTTPException(404, f"serial {serial}: not registered")
            return revoke_identity(s, serial, reason)

    rec = await _audited_write(rt, caller, "revoke", serial, {"reason": reason}, write)
    return _record_json(rec)


@router.get("/profiles", tags=["registry"], responses=_AUTH)
def profiles(request: Request, _caller: Caller = Depends(require("read_registry"))) -> list[dict[str, Any]]:
    """Airframe profiles that identities may declare."""
    from registry.dbapi import transaction
    from registry.store import list_profiles

    with transaction(runtime(request).settings.db_url) as s:
        return [p.to_dict(json=True) for p in list_profiles(s)]
