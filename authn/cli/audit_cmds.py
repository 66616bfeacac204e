"""`authn audit ...`: read and verify the hash-chained audit log."""

from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path

import typer

from authn.cli import CliState, app

audit_app = typer.Typer(help="Read and verify the tamper-evident audit log.", no_args_is_help=True)
app.add_typer(audit_app, name="audit")


def _entry_json(e) -> dict:
    return {"seq": e.seq, "created_at": e.created_at.isoformat(), "kind": e.kind, "serial": e.serial,
            "decision": e.decision, "payload": e.payload, "prev_hash": e.prev_hash, "entry_hash": e.entry_hash}


def _since(text: str | None) -> datetime | None:
    from authn.errors import AuthnError

    if text is None:
        return None
    try:
        when = datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        raise AuthnError(f"--since: not an ISO 8601 date/time: {text!r}") from None
    return when if when.tzinfo else when.replace(tzinfo=timezone.utc)


@audit_app.command("list")
def list_cmd(
    ctx: typer.Context,
    since: str | None = typer.Option(None, "--since", help="Only entries at or after this ISO 8601 time (UTC)."),
    decision: str | None = typer.Option(None, "--decision", help="accept or reject."),
    serial: str | None = typer.Option(None, "--serial", help="Only this claimed serial."),
    limit: int | None = typer.Option(None, "--limit", min=1, help="At most this many entries."),
    as_json: bool = typer.Option(False, "--json", help="JSON array instead of a table."),
) -> None:
    """List audit entries, oldest first.

    Example: authn audit list --decision reject --since 2026-01-01
    """
    from authn.audit import list_entries
    from authn.errors import AuthnError
    from registry.dbapi import Database

    if decision not in (None, "accept", "reject"):
        raise AuthnError(f"--decision: must be accept or reject, got {decision!r}")
    state: CliState = ctx.obj
    entries = list_entries(Database(state.db_url), since=_since(since), decision=decision, serial=serial,
                           limit=limit)
    if as_json:
        typer.echo(json.dumps([_entry_json(e) for e in entries], indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"audit log ({len(entries)} entries)")
    for col in ("seq", "time (UTC)", "kind", "serial", "decision", "reasons", "hash"):
        table.add_column(col)
    for e in entries:
        reasons = ", ".join(e.payload.get("reasons", [])) if e.kind == "decision" else e.payload.get("error", "")
        table.add_row(str(e.seq), e.created_at.strftime("%Y-%m-%d %H:%M:%S"), e.kind, e.serial or "",
                      e.decision or "", reasons, e.entry_hash[:12])
    Console().print(table)


@audit_app.command("show")
def show_cmd(ctx: typer.Context, seq: int = typer.Argument(..., help="Entry number (seq).")) -> None:
    """Print one audit entry as JSON (its evidence, policy and model digests, hashes).

    Example: authn audit show 42
    """
    from authn.audit import get_entry
    from authn.errors import AuthnError
    from registry.dbapi import Database

    entry = get_entry(Database(ctx.obj.db_url), seq)
    if entry is None:
        raise AuthnError(f"no audit entry {seq}")
    typer.echo(json.dumps(_entry_json(entry), indent=2))


@audit_app.command("verify")
def verify_cmd(
    ctx: typer.Context,
    against: Path | None = typer.Option(None, "--against", help="Checkpoint file from `authn audit export --checkpoint`."),
) -> None:
    """Recompute the hash chain and report the first bad entry (exit 1 when broken).

    With --against CHECKPOINT it also detects truncation and rewritten history.

    Example: authn audit verify --against audit-checkpoint.json
    """
    from authn.audit import Checkpoint, verify
    from authn.errors import AuthnError
    from registry.dbapi import Database

    cp = None
    if against is not None:
        try:
            cp = Checkpoint.from_json(against.read_text())
        except OSError as exc:
            raise AuthnError(f"{against}: cannot read checkpoint ({exc.strerror})") from None
    report = verify(Database(ctx.obj.db_url), cp)
    if report.ok:
        typer.echo(f"ok: {report.size} entries, head {report.head}")
        return
    typer.echo(f"BROKEN at entry {report.first_bad_seq}: {report.problem}", err=True)
    raise typer.Exit(1)


@audit_app.command("export")
def export_cmd(
    ctx: typer.Context,
    checkpoint_only: bool = typer.Option(False, "--checkpoint", help="Write only the head hash and size."),
    out: Path | None = typer.Option(None, "--out", help="Write to this file instead of stdout."),
) -> None:
    """Export the log as JSON lines, or a checkpoint (head hash + size) to keep elsewhere.

    Example: authn audit export --checkpoint --out audit-checkpoint.json
    """
    from authn.audit import checkpoint, list_entries
    from registry.dbapi import Database

    db = Database(ctx.obj.db_url)
    if checkpoint_only:
        text = checkpoint(db).to_json() + "\n"
    else:
        text = "".join(json.dumps(_entry_json(e), sort_keys=True) + "\n" for e in list_entries(db))
    if out is None:
        typer.echo(text, nl=False)
    else:
        out.write_text(text)
        typer.echo(f"wrote {out}")
