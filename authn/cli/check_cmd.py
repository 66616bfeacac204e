"""`authn check`: decide whether the observed drone is the identity it claims to be."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import typer

from authn.cli import app

BATCH_WRITE = 200  # audit entries per transaction in batch mode


def _files(paths: list[Path]) -> list[Path]:
    from authn.errors import AuthnError

    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            found = sorted(f for f in p.iterdir() if f.suffix.lower() in (".h5", ".hdf5", ".npz"))
            if not found:
                raise AuthnError(f"{p}: no .h5/.npz files in this directory")
            out.extend(found)
        else:
            out.append(p)
    return out


def _claims(path: Path) -> dict[str, str]:
    """file,serial CSV -> {file name or path: serial}."""
    from authn.errors import AuthnError

    try:
        rows = list(csv.DictReader(path.read_text().splitlines()))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise AuthnError(f"{path}: cannot read claims CSV ({exc})") from None
    if rows and not {"file", "serial"} <= set(rows[0]):
        raise AuthnError(f"{path}: claims CSV needs the columns file,serial")
    return {r["file"].strip(): r["serial"].strip() for r in rows if r.get("file") and r.get("serial")}


def _print_outcome(o) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    colour = "green" if o.decision == "accept" else "red"
    console.print(f"[bold {colour}]{o.decision.upper()}[/] {o.claim['serial']} ({o.claim['source']}) "
                  f"- {', '.join(o.reasons)}")
    t = Table(show_header=False, box=None, pad_edge=False)
    t.add_column(style="dim")
    t.add_column()
    reg = o.registry
    t.add_row("registry", f"{reg['status']}" + (f", declared {reg['model']}" if reg["model"] else ""))
    if o.radar is None:
        t.add_row("radar", "skipped (registry decided)")
    else:
        r = o.radar
        conf = "" if r["confidence"] is None else f" ({r['confidence']:.1%})"
        where = "" if r["range_m"] is None else f", {r['range_m']:.1f} m, {r['radial_velocity_mps']:+.2f} m/s"
        t.add_row("radar", f"{r['model']}{conf}{where}" + (", gated" if r.get("gated") else ""))
    if o.kinematics is not None:
        k = o.kinematics
        t.add_row("range residual", f"{k['range_residual_m']:.1f} m (tolerance {k['range_tolerance_m']:.1f} m)")
        if k["radial_velocity_residual_mps"] is not None:
            t.add_row("velocity residual", f"{k['radial_velocity_residual_mps']:.2f} m/s "
                      f"(tolerance {k['radial_velocity_tolerance_mps']:.2f} m/s)")
    if o.remote_id["issues"]:
        t.add_row("remote id issues", ", ".join(o.remote_id["issues"]))
    if o.skipped:
        t.add_row("skipped", ", ".join(o.skipped))
    t.add_row("time", f"{sum(o.timings_ms.values()):.1f} ms  audit #{o.audit_id}")
    console.print(t)


@app.command()
def check(
    ctx: typer.Context,
    files: list[Path] = typer.Argument(..., help="Recorded returns (.h5/.npz) or directories of them."),
    serial: str | None = typer.Option(None, "--serial", help="Claimed serial (default: the file's Remote ID)."),
    claims: Path | None = typer.Option(None, "--claims", help="CSV file,serial mapping files to claimed serials."),
    policy: Path | None = typer.Option(None, "--policy", help="Cedar policy file replacing the default."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON (one object; a list for several files)."),
) -> None:
    """Is the drone the radar sees really the registered UAV it claims to be?

    Exit code 0 accept, 1 reject, 2 bad input (one line on stderr; the failed
    check is still recorded in the audit log). With several files or a
    directory, checks them in one process (models load once) with a progress
    bar and a summary table; the exit code is the worst one.

    Example: authn check flight.h5 --serial 1581BDEM00000002 --json
    """
    from authn.check import Checker
    from authn.errors import bad_input_types

    state = ctx.obj
    bad = bad_input_types()
    try:
        checker = Checker(state.db_url, policy)
        paths = _files(files)
        mapping = _claims(claims) if claims else {}
    except bad as exc:
        _record_failure(state.db_url, [(str(f), serial, str(exc)) for f in files])
        raise
    if len(paths) == 1:
        _single(checker, paths[0], mapping.get(paths[0].name, mapping.get(str(paths[0]), serial)), as_json)
        return
    _batch(checker, paths, mapping, serial, as_json)


def _record_failure(db_url, rows) -> None:
    """Best effort: a check that could not even start is an audit error entry too."""
    from authn.audit import NewEntry, append
    from registry.dbapi import Database

    append(Database(db_url), [NewEntry("error", serial, None, {"file": f, "error": err}) for f, serial, err in rows])


def _single(checker, path: Path, serial: str | None, as_json: bool) -> None:
    from authn.errors import bad_input_types

    try:
        outcome = checker.evaluate(path, serial)
    except bad_input_types() as exc:
        checker.record([(str(path), serial, str(exc))])
        raise
    checker.record([outcome])
    if as_json:
        typer.echo(json.dumps(outcome.to_json(), indent=2))
    else:
        _print_outcome(outcome)
    raise typer.Exit(0 if outcome.decision == "accept" else 1)


def _batch(checker, paths: list[Path], mapping: dict[str, str], serial: str | None, as_json: bool) -> None:
    from rich.console import Console
    from rich.progress import Progress
    from rich.table import Table

    from authn.errors import bad_input_types

    bad = bad_input_types()
    results: list = []
    pending: list = []
    with Progress(transient=True, disable=as_json and not sys.stderr.isatty()) as progress:
        task = progress.add_task(f"checking {len(paths)} returns", total=len(paths))
        for p in paths:
            claim = mapping.get(p.name, mapping.get(str(p), serial))
            try:
                item = checker.evaluate(p, claim)
            except bad as exc:
                item = (str(p), claim, str(exc))
            results.append(item)
            pending.append(item)
            if len(pending) >= BATCH_WRITE:
                checker.record(pending)
                pending = []
            progress.advance(task)
        if pending:
            checker.record(pending)
    errors = [r for r in results if isinstance(r, tuple)]
    outcomes = [r for r in results if not isinstance(r, tuple)]
    if as_json:
        typer.echo(json.dumps([o.to_json() if not isinstance(o, tuple) else
                               {"file": o[0], "error": o[2]} for o in results], indent=2))
    else:
        table = Table(title=f"{len(paths)} returns: {sum(o.decision == 'accept' for o in outcomes)} accepted, "
                            f"{sum(o.decision == 'reject' for o in outcomes)} rejected, {len(errors)} bad input")
        for col in ("file", "serial", "decision"):
            table.add_column(col, overflow="fold")
        table.add_column("reasons", overflow="fold")
        table.add_column("radar")
        table.add_column("ms", justify="right")
        for r in results:
            if isinstance(r, tuple):
                table.add_row(Path(r[0]).name, r[1] or "", "[yellow]error[/]", r[2], "", "")
                continue
            radar = r.radar["model"] if r.radar else "skipped"
            colour = "green" if r.decision == "accept" else "red"
            table.add_row(Path(r.file).name, r.claim["serial"], f"[{colour}]{r.decision}[/]", ", ".join(r.reasons),
                          radar, f"{sum(r.timings_ms.values()):.1f}")
        Console().print(table)
    for f, _, err in errors:
        print(f"error: {f}: {err}", file=sys.stderr)
    raise typer.Exit(2 if errors else (1 if any(o.decision == "reject" for o in outcomes) else 0))
