"""`authn check --track`: one decision over a target's dwells (authn.track, docs/tracks.md).

The track is decided and its one audit entry committed (`authn.track.check_track`) before
anything is printed; exit 0 accept, 1 reject, 4 inconclusive, 2 bad input (an empty directory, mixed waveforms
or claims, dwells out of time order, an unreadable dwell), 3 system error."""

from __future__ import annotations

import json
from pathlib import Path

import typer


def run_track(checker, paths: list[Path], serial: str | None, sprt, as_json: bool) -> int:
    """Decide and record the track of `paths`; print it; return the exit code."""
    from authn.track import Dwell, check_track
    from core.errors import EXIT_BAD_INPUT, describe, exit_code_for, exit_code_of

    try:
        out = check_track(checker, [Dwell.file(p) for p in paths], serial, sprt)
    except Exception as exc:
        if as_json and exit_code_for(exc) == EXIT_BAD_INPUT:  # as check --json reports a bad file
            typer.echo(json.dumps({"file": str(paths[0]) if paths else "", "track": True, "error": describe(exc),
                                   "exit_code": EXIT_BAD_INPUT}, indent=2))
        raise
    if as_json:
        typer.echo(json.dumps(out.to_json(), indent=2))
    else:
        _print(out)
    return exit_code_of(out.decision)


def _print(out) -> None:
    """Human output: the decision, the test's state, one line per dwell read, the skipped ones."""
    from core.textsafe import printable

    s = out.sprt
    typer.echo(printable(f"{out.decision.upper()} {out.serial} ({out.evidence.claim.source}) - "
                         f"{', '.join(out.reasons)}"))
    typer.echo(f"  track    {out.dwells_used} of {len(out.dwells) + len(out.skipped)} dwells used, "
               f"{len(out.skipped)} skipped; LLR {out.llr:+.2f} nats (accept >= {s.accept_nats:.2f}, "
               f"reject <= {s.reject_nats:.2f}; false accept {s.false_accept:g}, false reject {s.false_reject:g})")
    typer.echo(printable(f"  why      {out.why()}"))
    for d in out.dwells:
        llr = "not verified" if d.llr is None else f"llr {d.llr:+.2f} -> {d.increment:+.2f}"
        kin = ""
        if d.kinematics and d.kinematics.get("range_residual_m") is not None:
            kin = f", range {d.kinematics['range_residual_m']:.1f}/{d.kinematics['range_tolerance_m']:.1f} m"
        typer.echo(printable(f"  dwell    {Path(d.file).name}: {d.radar_model or 'radar skipped'}, {llr}{kin}"))
    if out.skipped:
        typer.echo(printable(f"  skipped  {', '.join(Path(f).name for f in out.skipped)}"))
    if out.decision == "inconclusive":
        from authn.cli.output import to_decide_line

        typer.echo(printable(f"  decide   {to_decide_line(out.to_json()['to_decide'])}"))
    typer.echo(f"  time     {sum(out.timings_ms.values()):.1f} ms  audit #{out.audit_id}")
