"""`authn audit ...`: read, verify, checkpoint and prove the tamper-evident audit log.

Exit codes: 0 ok, 1 the log (or a proof, or a replay) does not hold, a head source it reads
is damaged, 2 bad input (a missing or malformed file named on the command line, a missing
confirmation), 3 system fault (log key, database).
"""

from __future__ import annotations

import json
from datetime import datetime
from pathlib import Path

import typer

from authn.cli.groups import subgroup
from authn.cli.state import CliState
from core.parsing import loads_json, parse_iso_time

LOG_KEY_HELP = "Ed25519 log key (PEM; default $AUTHN_LOG_KEY, else audit-log-key.pem in the user data dir)."
STH_LOG_HELP = "JSON-lines file of automatic signed tree heads (default $AUTHN_AUDIT_STH_LOG, else beside the key)."
WITNESS_HELP = "Witness of the log's heads: a folder or an http(s) URL (default $AUTHN_AUDIT_WITNESS)."

audit_app = typer.Typer(help="Read and verify the tamper-evident audit log.", no_args_is_help=True)


def _write(text: str, out: Path | None) -> None:
    from core.errors import AuthnError

    if out is None:
        typer.echo(text, nl=False)
        return
    try:
        out.write_text(text)
    except OSError as exc:
        raise AuthnError(f"{out}: cannot write ({exc.strerror})") from None
    typer.echo(f"wrote {out}", err=True)


def _entry_json(e) -> dict:
    return {"seq": e.seq, "created_at": e.created_at.isoformat(), "kind": e.kind, "serial": e.serial,
            "decision": e.decision, "payload": e.payload, "prev_hash": e.prev_hash, "entry_hash": e.entry_hash}


def _since(text: str | None) -> datetime | None:
    from core.errors import AuthnError

    if text is None:
        return None
    return parse_iso_time(text, "--since", error=AuthnError)


@audit_app.command("list")
def list_cmd(
    ctx: typer.Context,
    since: str | None = typer.Option(None, "--since", help="Only entries at or after this ISO 8601 time (UTC)."),
    decision: str | None = typer.Option(None, "--decision",
                                        help="accept, reject, error (error entries) or registry (registry changes)."),
    serial: str | None = typer.Option(None, "--serial", help="Only this claimed serial."),
    limit: int | None = typer.Option(None, "--limit", min=1, help="At most this many entries."),
    as_json: bool = typer.Option(False, "--json", help="JSON array instead of a table."),
) -> None:
    """List audit entries, oldest first.

    Example: authn audit list --decision reject --since 2026-01-01
    """
    from authn.audit import list_entries
    from core.errors import AuthnError
    from registry.dbapi import Database

    if decision not in (None, "accept", "reject", "inconclusive", "error", "registry"):
        raise AuthnError(f"--decision: must be accept, reject, inconclusive, error or registry, got {decision!r}")
    state: CliState = ctx.obj
    kind = decision if decision in ("error", "registry") else None
    entries = list_entries(Database(state.db_url), since=_since(since),
                           decision=None if kind else decision, kind=kind, serial=serial, limit=limit)
    if as_json:
        typer.echo(json.dumps([_entry_json(e) for e in entries], indent=2))
        return
    from rich.table import Table

    from authn.cli.output import print_table
    from core.textsafe import cell

    table = Table(title=f"audit log ({len(entries)} entries)",
                  caption="one entry in full, hashes included: `authn audit show SEQ`")
    table.add_column("seq", justify="right", no_wrap=True)
    table.add_column("time (UTC)", no_wrap=True)
    table.add_column("serial", no_wrap=True, min_width=16)  # identifiers: never split
    table.add_column("decision", no_wrap=True)
    table.add_column("reasons / error / change", overflow="fold", ratio=1)
    for e in entries:  # serials, errors and notes come from outside: escaped, never rich markup
        label, detail = _list_row(e)
        table.add_row(str(e.seq), e.created_at.strftime("%Y-%m-%d %H:%M"), cell(e.serial or ""),
                      cell(label), cell(detail))
    print_table(table)


def _list_row(e) -> tuple[str, str]:
    """The decision column and the reasons column of one entry: a decision with its reasons,
    an error with its message, a registry change (`authn serve`) as `registry` with what
    changed and who changed it."""
    p = e.payload if isinstance(e.payload, dict) else {}
    if e.kind == "decision":
        return str(e.decision), ", ".join(str(r) for r in p.get("reasons", []))
    if e.kind == "registry":
        action = str(p.get("action") or "change")
        extra = [f"{k} {p[k]}" for k in ("model", "reason") if p.get(k) is not None]
        by = f"by API key {p['api_key_id']}" + (f" ({p['role']})" if p.get("role") else "") \
            if p.get("api_key_id") is not None else ""
        parts = [action + (f" ({', '.join(extra)})" if extra else "")] + ([by] if by else [])
        if p.get("error"):
            parts.append(str(p["error"]))
        return "registry", "; ".join(parts)
    if e.kind == "error":
        return "error", str(p.get("error", ""))
    return str(e.decision or e.kind), str(p.get("error", ""))


@audit_app.command("show")
def show_cmd(ctx: typer.Context, seq: int = typer.Argument(..., help="Entry number (seq).")) -> None:
    """Print one audit entry as JSON (its evidence, policy and model digests, hashes).

    Example: authn audit show 42
    """
    from authn.audit import get_entry
    from core.errors import AuthnError
    from registry.dbapi import Database

    entry = get_entry(Database(ctx.obj.db_url), seq)
    if entry is None:
        raise AuthnError(f"no audit entry {seq}")
    typer.echo(json.dumps(_entry_json(entry), indent=2))




def _public_key(public_key: Path | None, log_key: Path | None, *, required: bool) -> object | None:
    """--public-key, else the public half of the log key file (None if absent and not required)."""
    from authn.audit.logkey import LogKey, key_path, load_public_key

    if public_key is not None:
        return load_public_key(public_key)
    if not required and not key_path(log_key).exists():
        return None
    return LogKey.load(log_key).public_key


def _broken(first_bad_seq: int | None, problem: str, as_json: bool) -> None:
    """`verify`'s exit 1: one JSON object on stdout, or one line on stderr naming the first bad entry."""
    if as_json:
        typer.echo(json.dumps({"ok": False, "first_bad_seq": first_bad_seq, "problem": problem}, indent=2))
    else:
        where = f" at entry {first_bad_seq}" if first_bad_seq is not None else ""
        typer.echo(f"BROKEN{where}: {problem}", err=True)
    raise typer.Exit(1)


@audit_app.command("verify")
def verify_cmd(
    ctx: typer.Context,
    against: Path | None = typer.Option(None, "--against", help="A signed head file (`authn audit checkpoint`)."),
    log_key: Path | None = typer.Option(None, "--log-key", help=LOG_KEY_HELP),
    public_key: Path | None = typer.Option(None, "--public-key",
                                           help="Check head signatures with this PEM public key."),
    sth_log: Path | None = typer.Option(None, "--sth-log", help=STH_LOG_HELP),
    witness: str | None = typer.Option(None, "--witness", help=WITNESS_HELP),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object (docs/audit.md)."),
) -> None:
    """Recompute the hash chain and the Merkle tree; check the log against signed heads.

    Without --against it uses every head found in the STH log file, the latest-head file,
    the database and the witness (and names the newest); as every append signs the head of
    the whole log, entries that no signed head covers are reported too (a forged append).
    With one, the log must hold at least its tree_size entries and a consistency proof must
    show the signed log is a prefix of today's: truncation, rewrites, deletions and
    reordering before the head's size are reported. A head that names another log (its
    checkpoint origin), a malformed row, a stored leaf hash that is missing or wrong, and a
    head source that is there but damaged (STH log lines that are not heads, a latest-head
    file that does not parse) are reported. Exit 1 names the first entry that differs;
    exit 2 for a --sth-log or --against file that is missing or malformed.

    Example: authn audit verify --against sth.json --witness /mnt/witness
    """
    from authn.audit import HeadPlaces, KnownHead, accepted_keys, newest, verify
    from authn.audit.logkey import key_path, load_retired_keys
    from authn.audit.tree_head import SignedTreeHead
    from core.errors import AuthnError
    from registry.dbapi import Database

    sth = SignedTreeHead.read(against) if against is not None else None
    if sth_log is not None and not sth_log.exists():
        raise AuthnError(f"--sth-log {sth_log}: no such file")
    db = Database(ctx.obj.db_url)
    retired = load_retired_keys(key_path(log_key)) if public_key is None else []
    if sth is not None:
        heads = [KnownHead(sth, f"--against {against}")]
        key = _public_key(public_key, log_key, required=True)
    else:
        heads, damage = HeadPlaces.of(db, sth_log=sth_log, log_key=log_key, witness=witness).all_heads_and_damage()
        key = _public_key(public_key, log_key, required=bool(heads))
        keys = accepted_keys(heads, key, retired) if heads else []
        forged = [h for h in heads if not any(h.sth.verify_signature(k) for k in keys)]
        if forged:
            h = min(forged, key=lambda h: h.sth.tree_size)
            damage.append(f"tree head of size {h.sth.tree_size} ({h.source}) is not signed by the log key "
                          "(forged or altered)")
        if damage:
            _broken(None, "; ".join(damage), as_json)
    report = verify(db, heads, public_key=key, retired=retired, require_signed_to_end=sth is None)
    best = newest(heads)
    if not report.ok:
        _broken(report.first_bad_seq, str(report.problem), as_json)
    if as_json:
        typer.echo(json.dumps({"ok": True, "first_bad_seq": None, "problem": None, "entries": report.size,
                               "chain_head": report.head, "tree_root": report.root, "heads": len(heads),
                               "newest_head": None if best is None else {"tree_size": best.sth.tree_size,
                                                                         "source": best.source},
                               "unsigned": report.unsigned}, indent=2))
        return
    line = f"ok: {report.size} entries, chain head {report.head[:16]}, tree root {report.root[:16]}"
    if best is None:
        line += "; no signed tree head found (truncation cannot be detected; run `authn audit checkpoint`)"
    else:
        line += (f"; consistent with the newest signed tree head (size {best.sth.tree_size}, {best.source})"
                 + (f" and {len(heads) - 1} older" if len(heads) > 1 else ""))
        if report.unsigned:
            line += f"; {report.unsigned} newer entries not yet signed"
    typer.echo(line)


@audit_app.command("checkpoint")
def checkpoint_cmd(
    ctx: typer.Context,
    out: Path | None = typer.Option(None, "--out", help="Write the head to this file instead of stdout."),
    note: bool = typer.Option(False, "--note", help="Write the bare C2SP signed note instead of JSON."),
    log_key: Path | None = typer.Option(None, "--log-key", help=LOG_KEY_HELP),
    sth_log: Path | None = typer.Option(None, "--sth-log", help=STH_LOG_HELP),
    witness: str | None = typer.Option(None, "--witness", help=WITNESS_HELP),
) -> None:
    """Verify the log against every head kept anywhere, then sign its head to keep elsewhere.

    The head is a C2SP checkpoint (authn-checkpoint/1 JSON, or with --note the signed note
    itself); it is also stored in the database, the STH log and the witness.

    Example: authn audit checkpoint --note --out /mnt/elsewhere/checkpoint-$(date +%F)
    """
    from authn.audit import checkpoint
    from core.errors import AuthnError
    from registry.dbapi import Database

    try:
        sth = checkpoint(Database(ctx.obj.db_url), log_key=log_key, sth_log=sth_log, witness=witness)
    except AuthnError as exc:
        if "does not verify" not in str(exc):
            raise
        typer.echo(f"BROKEN: {exc}", err=True)
        raise typer.Exit(1) from None
    _write(sth.note() if note else sth.to_json() + "\n", out)


@audit_app.command("rotate-key")
def rotate_key_cmd(
    ctx: typer.Context,
    log_key: Path | None = typer.Option(None, "--log-key", help=LOG_KEY_HELP),
    sth_log: Path | None = typer.Option(None, "--sth-log", help=STH_LOG_HELP),
    witness: str | None = typer.Option(None, "--witness", help=WITNESS_HELP),
) -> None:
    """Replace the log key on purpose, handing over from the old one.

    Verifies the log, signs its head with the old key and with a new one (verifiers accept
    the new key's heads and, through that pair, the old key's), publishes both (database,
    latest-head file, STH log, witness), appends the old public key to
    `<key>.retired.pub.pem`, keeps the old private key as `<key>.retired-<id>.pem` (move it
    offline), and puts the new key in place. Give verifiers the new public key.

    Example: authn audit rotate-key --witness /mnt/witness
    """
    from authn.audit import rotate_key
    from core.errors import AuthnError
    from registry.dbapi import Database

    try:
        sth, kept = rotate_key(Database(ctx.obj.db_url), log_key=log_key, sth_log=sth_log, witness=witness)
    except AuthnError as exc:
        if "does not verify" not in str(exc):
            raise
        typer.echo(f"BROKEN: {exc}", err=True)
        raise typer.Exit(1) from None
    typer.echo(f"rotated: head of size {sth.tree_size} signed by the old and the new key; "
               f"new key id {sth.log_key_id[:16]}; old private key kept at {kept}")


@audit_app.command("recover")
def recover_cmd(
    ctx: typer.Context,
    trust_root: str | None = typer.Option(None, "--trust-root",
                                          help="The tree root of the entries you trust as they stand "
                                               "(a run without it prints it)."),
    log_key: Path | None = typer.Option(None, "--log-key", help=LOG_KEY_HELP),
    sth_log: Path | None = typer.Option(None, "--sth-log", help=STH_LOG_HELP),
    witness: str | None = typer.Option(None, "--witness", help=WITNESS_HELP),
) -> None:
    """Sign a log that no signed head vouches for, as it stands, and record that in the log.

    Appends refuse such a log (its heads deleted, its key lost, a log from before signing).
    Without --trust-root this prints how many entries there are and their tree root, and
    exits 2; with it (that root), the log must be a whole chain consistent with every head
    still found (else exit 1). It appends an `audit` entry naming what was trusted, signs a
    head over everything (with a new key when the key file is gone and no head is left) and
    publishes it. Exit 0 also when a signed head already vouches for every entry.

    Example: authn audit recover --trust-root 5d41402abc4b2a76b9719d911017c592
    """
    from authn.audit import recover
    from core.errors import AuthnError
    from registry.dbapi import Database

    try:
        done = recover(Database(ctx.obj.db_url), trust_root, log_key=log_key, sth_log=sth_log, witness=witness)
    except AuthnError as exc:
        if "does not verify" not in str(exc):
            raise
        typer.echo(f"BROKEN: {exc}", err=True)
        raise typer.Exit(1) from None
    if done.seq is None or done.head is None:
        typer.echo(f"ok: nothing to recover: a signed head vouches for all {done.entries} entries")
        return
    typer.echo(f"recovered: entries 1..{done.entries} trusted as they stood (tree root {done.root}; "
               f"{done.vouched} were vouched for), recorded as entry {done.seq}, head of size {done.head.tree_size} "
               f"signed by {'a new' if done.new_key else 'the'} log key {done.head.log_key_id[:16]}")


@audit_app.command("public-key")
def public_key_cmd(
    ctx: typer.Context,
    out: Path | None = typer.Option(None, "--out", help="Write the PEM to this file instead of stdout."),
    log_key: Path | None = typer.Option(None, "--log-key", help=LOG_KEY_HELP),
) -> None:
    """Print the log's Ed25519 public key (PEM) and its key id, for verifiers.

    The key is created here only for a log that has no signed head yet.

    Example: authn audit public-key --out authn-log.pub
    """
    from authn.audit import known_heads, writer_key
    from registry.dbapi import Database

    db = Database(ctx.obj.db_url)
    key = writer_key(db, known_heads(db, log_key=log_key), log_key)
    _write(key.public_pem(), out)
    typer.echo(f"log_key_id {key.key_id}", err=True)


witness_app = subgroup(audit_app, "witness", "Run a witness of audit log heads on another host.",
                       "authn audit witness serve --dir /srv/authn-witness --public-key authn-log.pub")


@witness_app.command("serve")
def witness_serve_cmd(
    folder: Path = typer.Option(..., "--dir", help="Where the witnessed heads are kept (append-only files)."),
    public_key: list[Path] = typer.Option(..., "--public-key", help="The log's public key(s) (PEM); repeatable."),
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on."),
    port: int = typer.Option(8090, "--port", min=1, max=65535, help="TCP port."),
) -> None:
    """Keep every head a log publishes, each proven to extend the last (C2SP tlog-witness style).

    The log publishes with `--witness http://HOST:PORT` (or $AUTHN_AUDIT_WITNESS). A head
    that does not extend the newest one held is refused (409) and never stored.

    Example: authn audit witness serve --dir /srv/authn-witness --public-key authn-log.pub --port 8090
    """
    from authn.audit.logkey import load_public_key
    from authn.audit.witness import WitnessStore, serve

    keys = [load_public_key(p) for p in public_key]
    typer.echo(f"authn witness: http://{host}:{port}, heads in {folder}", err=True)
    serve(WitnessStore(folder), keys, host, port)


@audit_app.command("prove")
def prove_cmd(
    ctx: typer.Context,
    seq: int = typer.Argument(..., help="Entry number (seq)."),
    sth_file: Path | None = typer.Option(None, "--sth",
                                         help="Prove against this STH (default: the newest covering N)."),
    out: Path | None = typer.Option(None, "--out", help="Write the proof to this file instead of stdout."),
    log_key: Path | None = typer.Option(None, "--log-key", help=LOG_KEY_HELP),
    sth_log: Path | None = typer.Option(None, "--sth-log", help=STH_LOG_HELP),
) -> None:
    """A self-contained inclusion proof of entry N: the entry, its audit path, the STH.

    A third party checks it with `authn audit verify-proof PROOF --public-key KEY`.

    Example: authn audit prove 42 --out entry-42.proof.json
    """
    from authn.audit import prove
    from core.errors import AuthnError
    from authn.audit.tree_head import SignedTreeHead
    from registry.dbapi import Database

    sth = SignedTreeHead.read(sth_file) if sth_file is not None else None
    if sth is not None and not sth.verify_signature(_public_key(None, log_key, required=True)):
        raise AuthnError(f"{sth_file}: not signed by the log key")
    doc = prove(Database(ctx.obj.db_url), seq, sth, log_key=log_key, sth_log=sth_log)
    _write(json.dumps(doc, indent=2, sort_keys=True) + "\n", out)


@audit_app.command("verify-proof")
def verify_proof_cmd(
    proof: Path = typer.Argument(..., help="Proof file from `authn audit prove`."),
    public_key: Path = typer.Option(..., "--public-key", help="The log's public key (`authn audit public-key`)."),
) -> None:
    """Check an inclusion proof with only the log's public key (no database). Exit 1 if it fails.

    Example: authn audit verify-proof entry-42.proof.json --public-key authn-log.pub
    """
    from authn.audit import verify_proof
    from core.errors import AuthnError
    from authn.audit.logkey import load_public_key

    key = load_public_key(public_key)
    try:
        doc = loads_json(proof.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise AuthnError(f"{proof}: cannot read proof ({exc.strerror})") from None
    except (UnicodeDecodeError, ValueError):
        raise AuthnError(f"{proof}: not a JSON proof document") from None
    try:
        line = verify_proof(doc, key)
    except AuthnError as exc:
        typer.echo(f"FAILED: {exc}", err=True)
        raise typer.Exit(1) from None
    typer.echo(line)


@audit_app.command("replay")
def replay_cmd(ctx: typer.Context, seq: int = typer.Argument(..., help="Entry number (seq)."),
               as_json: bool = typer.Option(False, "--json", help="Print one JSON object (docs/audit.md).")) -> None:
    """Re-decide entry N with the recorded policy text and inputs; exit 0 same, 1 different.

    Entries without recorded policy inputs (older ones, errors): "not replayable", exit 2.

    Example: authn audit replay 42
    """
    from authn.audit import replay
    from registry.dbapi import Database

    r = replay(Database(ctx.obj.db_url), seq)
    if as_json:
        typer.echo(json.dumps({"seq": seq, "same": r.same, "policy_sha256": r.policy_sha256,
                               "recorded": {"decision": r.recorded[0], "reasons": list(r.recorded[1])},
                               "replayed": {"decision": r.replayed[0], "reasons": list(r.replayed[1])}}, indent=2))
        if not r.same:
            raise typer.Exit(1)
        return
    rec = f"{r.recorded[0]} [{', '.join(r.recorded[1])}]"
    now = f"{r.replayed[0]} [{', '.join(r.replayed[1])}]"
    if r.same:
        typer.echo(f"same: entry {seq} replays to {now} under policy {r.policy_sha256[:16]}")
        return
    typer.echo(f"DIFFERENT: entry {seq} recorded {rec}, replays to {now} under policy {r.policy_sha256[:16]}")
    raise typer.Exit(1)


@audit_app.command("export")
def export_cmd(
    ctx: typer.Context,
    checkpoint_only: bool = typer.Option(False, "--checkpoint",
                                         help="Write a signed tree head instead (as `checkpoint`)."),
    out: Path | None = typer.Option(None, "--out", help="Write to this file instead of stdout."),
    folder: Path | None = typer.Option(None, "--dir", help="Write the verifiable export into this folder: the leaf "
                                       "bytes, the newest checkpoint and the public key (docs/audit.md)."),
    log_key: Path | None = typer.Option(None, "--log-key", help=LOG_KEY_HELP),
) -> None:
    """Export the log as JSON lines, a signed tree head to keep elsewhere, or a folder to verify.

    With --dir: the leaf bytes of every entry the newest checkpoint covers, that checkpoint
    and the public key; `python tools/verify_audit_export.py DIR` checks the folder without
    authn. Exit 1 when the stored log does not make the tree the checkpoint signed.

    Example: authn audit export --dir audit-export
    """
    from authn.audit import checkpoint, export, list_entries
    from authn.audit.export import NotExportable
    from core.errors import AuthnError
    from registry.dbapi import Database

    db = Database(ctx.obj.db_url)
    if folder is not None:
        if checkpoint_only or out is not None:
            raise AuthnError("--dir writes its own files: not with --checkpoint or --out")
        try:
            done = export(db, folder, log_key=log_key)
        except NotExportable as exc:
            _broken(None, str(exc), False)
        typer.echo(f"exported {done.entries} entries to {done.folder} (tree root {done.root})")
        return
    if checkpoint_only:
        text = checkpoint(db, log_key=log_key).to_json() + "\n"
    else:
        text = "".join(json.dumps(_entry_json(e), sort_keys=True) + "\n" for e in list_entries(db))
    _write(text, out)
