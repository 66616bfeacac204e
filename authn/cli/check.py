"""`authn check`: decide whether the observed drone is the identity it claims to be."""

from __future__ import annotations

import json
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from authn.cli.output import DECISION_COLOURS, to_decide_line
from authn.cli.signals import handled, interrupted

if TYPE_CHECKING:
    from authn.check import Outcome, RidCapture

#: Files decided and recorded together (`Checker.check`: their radar stages batched, one audit
#: transaction, then printed): the first chunk is small so results start soon, each next one
#: twice as large up to CHECK_CHUNK. A crash or kill loses at most the chunk in flight, never a
#: printed decision. A stop signal is read before each file: the files read so far are still
#: decided, committed and printed.
FIRST_CHUNK = 8
CHECK_CHUNK = 256


def _files(paths: list[Path]) -> list[Path]:
    from core.errors import AuthnError

    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            from signatures.recording import recordings_in

            found = recordings_in(p)
            if not found:
                raise AuthnError(f"{p}: no .h5/.npz files in this directory")
            out.extend(found)
        else:
            out.append(p)
    return out


def _claims(path: Path) -> dict[str, str]:
    """file,serial CSV -> {file name or path: serial}; a row with a rid_capture column may leave
    the serial empty (every drone heard in the capture is then a claim)."""
    import csv

    from core.errors import AuthnError

    try:
        reader = csv.DictReader(path.read_text().splitlines())
        header = {h.strip() for h in reader.fieldnames or ()}
        rows = list(reader)
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise AuthnError(f"{path}: cannot read claims CSV ({exc})") from None
    if not {"file", "serial"} <= header:
        raise AuthnError(f"{path}: claims CSV needs a header row naming the columns file,serial")
    claims: dict[str, str] = {}
    for line, row in enumerate(rows, start=2):
        file, claimed = (row.get("file") or "").strip(), (row.get("serial") or "").strip()
        capture = (row.get("rid_capture") or "").strip()
        if not file or not (claimed or capture):
            raise AuthnError(f"{path}: line {line}: needs a file and a serial (or a rid_capture)")
        if claimed:
            claims[file] = claimed
    return claims


def _captures(path: Path) -> dict[str, Path]:
    """The optional rid_capture column of the claims CSV -> {file: capture path}; a relative
    capture path is taken from the CSV's folder."""
    import csv

    try:
        rows = list(csv.DictReader(path.read_text().splitlines()))
    except (OSError, UnicodeDecodeError, csv.Error):
        return {}  # _claims already reported it
    out: dict[str, Path] = {}
    for row in rows:
        file, capture = (row.get("file") or "").strip(), (row.get("rid_capture") or "").strip()
        if file and capture:
            out[file] = path.parent / capture
    return out


def _print_outcome(o: Outcome) -> None:
    """The human output of one decision: a headline, then a label/value table; as plain text
    when rich would print it without colour (`authn.cli.plaintext`), else through rich."""
    from authn.cli import plaintext
    from core.textsafe import printable

    headline = printable(f" {o.evidence.claim.serial} ({o.evidence.claim.source}) - {', '.join(o.reasons)}")
    rows = _outcome_rows(o)
    width = plaintext.console_width()
    plain_rows = [(label, value if markup else printable(value)) for label, value, markup in rows]
    text = None if width is None else plaintext.render(o.decision.upper() + headline, plain_rows, width)
    if text is not None:
        sys.stdout.write(text)
        return
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    from core.textsafe import cell

    console = Console()
    console.print(Text.assemble((o.decision.upper(), f"bold {DECISION_COLOURS.get(o.decision, 'red')}"), headline))
    t = Table(show_header=False, box=None, pad_edge=False)
    t.add_column(style="dim")
    t.add_column()
    for label, value, markup in rows:
        t.add_row(label, value if markup else cell(value))
    console.print(t)


def _outcome_rows(o: Outcome) -> list[tuple[str, str, bool]]:
    """(label, value, is rich markup) rows of the human output: a value that is not markup is
    untrusted text, printed escaped (`core.textsafe`); markup values are numbers and dates."""
    from datetime import datetime, timezone

    ev = o.evidence
    rows: list[tuple[str, str, bool]] = []
    reg = ev.registry
    rows.append(("registry", reg.status + (f", declared {reg.model}" if reg.model else ""), False))
    if "outside-validity-window" in o.reasons and reg.valid_from is not None:
        dwell = datetime.fromtimestamp(ev.time_s, timezone.utc).isoformat()
        rows.append(("validity", f"dwell at {dwell}; registered valid from {reg.valid_from.isoformat()}"
                     + (f" until {reg.valid_until.isoformat()}" if reg.valid_until else ""), True))
    r = ev.radar
    if r is None:
        rows.append(("radar", "skipped (registry decided)", True))
    else:
        conf = "" if r.confidence is None else f" ({r.confidence:.1%})"
        where = "" if r.radial_velocity_mps is None else (
            (f", {r.range_m:.1f} m" if r.range_m is not None else ", range not measured")
            + f", {r.radial_velocity_mps:+.2f} m/s")
        rows.append(("radar", f"{r.model}{conf}{where}" + (", gated" if r.gated else ""), False))
    k = ev.kinematics
    if k is not None:
        res = k.residuals
        if k.range_measured:
            rows.append(("range residual",
                         f"{res.range_residual_m:.1f} m (tolerance {res.range_tolerance_m:.1f} m)", True))
        if res.radial_velocity_residual_mps is not None:
            rows.append(("velocity residual", f"{res.radial_velocity_residual_mps:.2f} m/s "
                         f"(tolerance {res.radial_velocity_tolerance_mps:.2f} m/s)", True))
    auth = ev.auth
    if auth.status != "absent":  # signed Remote ID: what the signature came to
        what = auth.status + (f" ({', '.join(auth.sam_types)})" if auth.sam_types else "")
        what += f", covers {len(auth.covered)} messages" if auth.status == "valid" else ""
        rows.append(("remote id auth", what + (f": {auth.reason}" if auth.reason else ""), False))
    if ev.remote_id_issues:
        rows.append(("remote id issues", ", ".join(ev.remote_id_issues), False))
    if o.non_cooperative:  # with --rid-capture: radar targets no broadcast explains
        rows.append(("non-cooperative",
                     ", ".join(f"{x['range_m']:.1f} m ({x['snr_db']:.0f} dB)" for x in o.non_cooperative), True))
    v = r.verification if r is not None else None
    if v is not None and v.terms:
        rows.append(("verification", f"LLR {v.llr:+.2f} nats against {v.closest}"
                     + (f" (of {', '.join(sorted(v.against))})" if len(v.against) > 1 else ""), False))
    if o.decision == "inconclusive":
        rows.append(("to decide", to_decide_line(ev.to_decide()), False))
    if o.skipped:
        rows.append(("skipped", ", ".join(o.skipped), False))
    rows.append(("time", f"{sum(o.timings_ms.values()):.1f} ms  audit #{o.audit_id}", True))
    return rows


def check(
    ctx: typer.Context,
    files: list[Path] = typer.Argument(..., help="Recorded returns (.h5/.npz) or directories of them."),
    serial: str | None = typer.Option(None, "--serial", help="Claimed serial (default: the file's Remote ID)."),
    claims: Path | None = typer.Option(None, "--claims", help="CSV file,serial mapping files to claimed serials."),
    policy: Path | None = typer.Option(None, "--policy", help="Cedar policy file replacing the default."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON (one object; a list for several files)."),
    trust_registry: Path | None = typer.Option(None, "--trust-registry",
                                               help="JSON of registries (HDA DET + key) whose DRIP Links to trust."),
    model: Path | None = typer.Option(None, "--model",
                                      help="Classifier bundle folder to use (its waveform must be the file's; "
                                           "default: chosen by the file's waveform)."),
    cluster: str | None = typer.Option(None, "--cluster",
                                       help="Check in partitions on Dask workers: 'local' (one per core) or a "
                                            "scheduler address (needs the cluster extra; docs/cluster.md)."),
    partition_size: int | None = typer.Option(None, "--partition-size", min=1,
                                              help="Files per --cluster partition (default: 4 per worker, <= 250)."),
    rid_capture: Path | None = typer.Option(None, "--rid-capture",
                                            help="pcap/pcapng Remote ID capture heard beside the radar: each drone "
                                                 "heard in the dwell's window is a claim (docs/remoteid.md)."),
    rid_skew: float = typer.Option(2.0, "--rid-skew", min=0.0, max=3600.0,
                                   help="Clock-skew tolerance (s) between the capture and the radar."),
    max_drones: int = typer.Option(64, "--max-drones", min=1, max=1_000_000,
                                   help="Most drones one capture may name in a dwell's window (one decision "
                                        "each); more is bad input, refused before any is decided."),
    plot: Path | None = typer.Option(None, "--plot", help="Write one evidence figure (PNG) per decision into this "
                                                          "folder (the plot extra; docs/output.md)."),
    track: bool = typer.Option(False, "--track", help="The files (or the one directory) are dwells of one target "
                                                      "with one claim, in time order: one decision by a sequential "
                                                      "test, stopping at the first dwell that decides "
                                                      "(docs/tracks.md)."),
    false_accept: float = typer.Option(1e-3, "--false-accept",
                                       help="Target rate of accepting an impostor (Wald's alpha): one dwell is "
                                            "a track of one, decided by the same test."),
    false_reject: float = typer.Option(1e-2, "--false-reject",
                                       help="Target rate of rejecting a genuine claim (Wald's beta)."),
) -> None:
    """Is the drone the radar sees really the registered UAV it claims to be?

    Exit code 0 accept, 1 reject, 2 bad input, 3 system error (database, policy
    engine, models), 4 inconclusive (the radar's evidence reached neither bound
    of the sequential test: never an accept; the output says what would decide
    it); errors are one line on stderr and every failed check is
    still recorded in the audit log. A decision is printed only after its audit
    entry committed. With several files or a directory, checks them in one
    process (models load once) with a progress bar: each file's decision or
    error is audited as the batch goes (a bad or crashing file does not stop
    it; SIGINT/SIGTERM stop it after committing what was decided), and the
    exit code is the worst one (3 > 2 > 1 > 4 > 0).

    Example: authn check flight.h5 --serial 1581BDEM00000002 --json

    Example: authn check --track dwells/ --json
    """
    from authn.check import Checker, Failure

    state = ctx.obj
    track_started = False
    try:
        trusted = None
        if trust_registry:
            from authn.uakeys import load_trusted_registries

            trusted = load_trusted_registries(trust_registry)
        from authn.sprt import Sprt

        sprt = Sprt(false_accept, false_reject)
        checker = Checker(state.db_url, policy, trusted, model=model, sprt=sprt)
        if track:  # one target's dwells, one decision (authn.track)
            paths = _track_setup(files, claims, cluster, rid_capture, plot)
            from authn.cli.track import run_track

            track_started = True  # from here the track records its own failure (authn.track.check_track)
            raise typer.Exit(run_track(checker, paths, serial, sprt, as_json))
        paths = _files(files)
        mapping = _claims(claims) if claims else {}
        captures = _captures(claims) if claims else {}
        if cluster is not None and (rid_capture is not None or captures):
            from core.errors import AuthnError

            raise AuthnError("--rid-capture (or a rid_capture column) is not supported with --cluster yet")
    except typer.Exit:
        raise
    except Exception as exc:
        if not track_started:
            _record_failure(state.db_url, [Failure.of(str(f), serial, exc) for f in files])
        raise
    capture_of = _capture_of(captures, rid_capture, rid_skew, max_drones)
    if cluster is not None:  # the engine is imported only here (a cold check never loads it)
        from authn.cluster.recheck import cli_recheck

        raise typer.Exit(cli_recheck(checker, paths, mapping, serial, cluster, partition_size, as_json,
                                     policy=policy, trusted=trusted, model=model))
    figures = _Figures(plot) if plot is not None else None
    if len(paths) == 1:
        _single(checker, paths[0], mapping.get(paths[0].name, mapping.get(str(paths[0]), serial)), as_json,
                capture_of(paths[0]), figures)
        return
    _batch(checker, paths, mapping, serial, as_json, capture_of, figures)


def _capture_of(captures: dict[str, Path], rid_capture: Path | None, skew_s: float,
                max_drones: int) -> Callable[[Path], RidCapture | None]:
    """Which Remote ID capture a file is checked with: its row's in the claims CSV, else
    `--rid-capture`, else none."""
    if rid_capture is None and not captures:
        return lambda p: None
    from authn.check import RidCapture

    def capture_of(p: Path) -> RidCapture | None:
        c = captures.get(p.name, captures.get(str(p), rid_capture))
        return None if c is None else RidCapture.file(c, skew_s, max_drones)
    return capture_of


def _track_setup(files: list[Path], claims, cluster, rid_capture, plot):
    """The dwells of `--track`; the options a track does not take are bad input."""
    from authn.track import track_files
    from core.errors import AuthnError

    extra = [n for n, v in (("--claims", claims), ("--cluster", cluster), ("--rid-capture", rid_capture),
                            ("--plot", plot)) if v is not None]
    if extra:
        raise AuthnError(f"--track takes one claim over its dwells: {', '.join(extra)} cannot be used with it")
    return track_files(files)


class _Figures:
    """`--plot DIR`: the evidence figure of each recorded decision (authn.figure),
    `<file>-audit<id>.png` by the decision's audit entry, so a later decision on the same file
    never overwrites an earlier one's figure (nor does anything else: an existing name gets a
    `-2`, `-3` ... suffix); each path on stderr."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def __call__(self, outcomes: list) -> None:
        from authn.check import Outcome
        from authn.figure import draw
        from signatures.recording import read_recording

        for o in outcomes:
            if isinstance(o, Outcome):
                path = draw(read_recording(o.file), o.to_json(), self._free(f"{Path(o.file).stem}-audit{o.audit_id}"))
                typer.echo(f"wrote {path}", err=True)

    def _free(self, stem: str) -> Path:
        """`DIR/<stem>.png`, or the first `DIR/<stem>-N.png` that does not exist yet."""
        path, n = self.folder / f"{stem}.png", 1
        while path.exists():
            n += 1
            path = self.folder / f"{stem}-{n}.png"
        return path


def _record_failure(db_url, failures) -> None:
    """A check that could not even start is an audit error entry too. If the audit itself is
    what failed, the original error is the one reported (exit code by its kind)."""
    from authn.audit import AuditLog
    from registry.dbapi import Database

    try:
        AuditLog(Database(db_url)).record([f.entry(None) for f in failures])
    except Exception:  # noqa: BLE001 - the caller re-raises the error that stopped the check
        pass


def _single(checker, path: Path, serial: str | None, as_json: bool, capture=None, figures=None) -> None:
    from authn.check import CheckInput, Failure
    from core.errors import EXIT_BAD_INPUT, exit_code_of, worst

    items = checker.check([CheckInput.file(path, serial, capture)]).items  # recorded, or it raised
    outcome = items[0]
    if isinstance(outcome, Failure):
        if as_json and outcome.exit_code == EXIT_BAD_INPUT:  # as a batch reports a bad file: in its JSON
            typer.echo(json.dumps(outcome.to_json(), indent=2))
        outcome.raise_()
    if figures is not None:
        figures(items)
    if len(items) > 1:  # a capture with several drones: one decision each, a JSON array
        if as_json:
            typer.echo(json.dumps([o.to_json() for o in items], indent=2))
        else:
            for o in items:
                _print_outcome(o)
        raise typer.Exit(worst([exit_code_of(o.decision) for o in items]))
    if as_json:
        typer.echo(json.dumps(outcome.to_json(), indent=2))
    else:
        _print_outcome(outcome)
    raise typer.Exit(exit_code_of(outcome.decision))


@contextmanager
def _stop_signals() -> Iterator[list[int]]:
    """The first SIGINT/SIGTERM sets a flag the batch loop reads between files; a second one
    raises at once."""
    stop: list[int] = []

    def handler(signum: int, _frame: object) -> None:
        if stop:
            raise interrupted(signum)
        stop.append(signum)

    with handled(handler):
        yield stop


def _batch(checker, paths: list[Path], mapping: dict[str, str], serial: str | None, as_json: bool,
           capture_of=lambda p: None, figures=None) -> None:
    from rich.progress import Progress

    from authn.check import CheckInput, Failure
    from core.errors import Interrupted, exit_code_of, worst

    results: list = []
    out = sys.stdout
    first = [True]

    def emit(item) -> None:
        results.append(item)
        if as_json:  # a JSON array streamed as it is committed
            out.write(("[\n" if first[0] else ",\n") + json.dumps(item.to_json(), indent=2))
            out.flush()
            first[0] = False

    from rich.console import Console

    bar = Progress(transient=True, console=Console(stderr=True), disable=not sys.stderr.isatty())  # never on stdout
    with _stop_signals() as stop, bar as progress:
        task = progress.add_task(f"checking {len(paths)} returns", total=len(paths))
        start, size = 0, FIRST_CHUNK
        while start < len(paths) and not stop:
            chunk = paths[start:start + size]
            batch = checker.check([CheckInput.file(p, mapping.get(p.name, mapping.get(str(p), serial)), capture_of(p))
                                   for p in chunk], stop=lambda: bool(stop))
            for item in batch.items:  # recorded: printed only now
                emit(item)
            if figures is not None:
                figures(batch.items)
            if batch.fault is not None:  # the database or policy engine: the batch cannot go on
                raise batch.fault
            progress.advance(task, len({r.file for r in batch.items}))
            start, size = start + len(chunk), min(2 * size, CHECK_CHUNK)
    if as_json:
        out.write(("[" if first[0] else "\n") + "]\n")
    else:
        _print_summary(results, len(paths))
    failures = [r for r in results if isinstance(r, Failure)]
    from core.textsafe import printable

    for f in failures:
        named = f.error.startswith(f"{f.file}:")  # the reader's messages name the file already
        print(printable(f"error: {f.error}" if named else f"error: {f.file}: {f.error}"), file=sys.stderr)
    if stop:
        raise Interrupted(f"interrupted by {signal.Signals(stop[0]).name} after {len(results)} of {len(paths)} "
                          "returns; every printed result is in the audit log", stop[0])
    codes = [f.exit_code for f in failures] + [exit_code_of(o.decision) for o in results if not isinstance(o, Failure)]
    raise typer.Exit(worst(codes))


def _print_summary(results: list, total: int) -> None:
    from rich.console import Console
    from rich.table import Table

    from authn.cli.output import print_table
    from authn.check import Failure
    from core.textsafe import cell

    outcomes = [r for r in results if not isinstance(r, Failure)]
    failures = [r for r in results if isinstance(r, Failure)]
    table = Table(title=f"{total} returns: {sum(o.decision == 'accept' for o in outcomes)} accepted, "
                        f"{sum(o.decision == 'reject' for o in outcomes)} rejected, "
                        f"{sum(o.decision == 'inconclusive' for o in outcomes)} inconclusive, {len(failures)} errors")
    for col in ("file", "serial", "decision"):  # identifiers: never split
        table.add_column(col, no_wrap=True)
    table.add_column("reasons", overflow="fold")
    table.add_column("radar", no_wrap=True)
    table.add_column("ms", justify="right", no_wrap=True)
    for r in results:
        if isinstance(r, Failure):
            table.add_row(cell(Path(r.file).name), cell(r.serial), "[yellow]error[/]", cell(r.error), "", "")
            continue
        radar = r.radar.model if r.radar else "skipped"
        colour = DECISION_COLOURS.get(r.decision, "red")
        table.add_row(cell(Path(r.file).name), cell(r.serial), f"[{colour}]{r.decision}[/]",
                      cell(", ".join(r.reasons)), cell(radar), f"{sum(r.timings_ms.values()):.1f}")
    print_table(table, Console())  # piped: one tab-separated line per return
