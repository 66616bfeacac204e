"""`authn demo`: the whole product on a fresh install, in one command."""

from __future__ import annotations

import json
import time
from pathlib import Path

import typer

from authn.cli.output import DECISION_COLOURS


def demo(
    ctx: typer.Context,
    out: Path | None = typer.Option(None, "--out", help="Where to write the simulated returns "
                                    "(default: a 'demo' folder in the user cache directory)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object: each scene's decision."),
) -> None:
    """Register example UAVs, simulate nine scenes, check each and print the decisions.

    The scenes: a genuine flight, a spoofed type (a Phantom 4 claiming an M600's
    serial), a position spoofed by 300 m, an unregistered serial, a revoked one and a
    bird; then signed Remote ID (IETF DRIP): an M300 registered with a key signs its
    broadcast, and another M300 claims that identity unsigned and signed with its own
    key. The keys are generated on every run; the keyed identity is registered under
    its DRIP session ID. Uses the default SQLite registry unless --db /
    AUTHN_DATABASE_URL says otherwise. Exit code 0 when every decision is the expected one.

    Example: authn demo
    """
    from platformdirs import user_cache_dir
    from rich.console import Console
    from rich.table import Table

    from authn.check import Checker
    from authn.cli.output import print_table
    from authn.demo import DemoKeys, claimed_serial, register_examples, write_scenes

    t0 = time.perf_counter()
    console = Console()
    out = out or Path(user_cache_dir("authn")) / "demo"
    out.mkdir(parents=True, exist_ok=True)
    keys = DemoKeys.generate()
    register_examples(ctx.obj.db_url, keys)
    scenes = write_scenes(out, keys=keys)
    checker = Checker(ctx.obj.db_url)
    outcomes = [checker.evaluate(path, None if sc.broadcast else claimed_serial(sc, keys)) for sc, path in scenes]
    seqs = checker.record(outcomes)
    if as_json:
        scenes_json = [{"seq": seq, "scene": sc.name, "file": str(path), "expected": sc.expected,
                        "decision": o.decision, "reasons": list(o.reasons),
                        "claimed": o.evidence.registry.model or o.evidence.registry.status,
                        "radar": None if o.radar is None else {"model": o.radar.model,
                                                              "confidence": o.radar.confidence}}
                       for (sc, path), o, seq in zip(scenes, outcomes, seqs)]
        ok = all(s["decision"] == s["expected"] for s in scenes_json)
        typer.echo(json.dumps({"ok": ok, "out": str(out), "seconds": round(time.perf_counter() - t0, 3),
                               "scenes": scenes_json}, indent=2))
        raise typer.Exit(0 if ok else 1)
    table = Table(title="authn demo: is the drone the radar sees the UAV it claims to be?")
    for col in ("#", "scene", "claimed", "radar sees", "decision"):
        table.add_column(col, no_wrap=True)  # identifiers: never split
    table.add_column("reasons", overflow="fold")  # prose: wraps between reasons
    all_ok = True
    for (sc, _path), o, seq in zip(scenes, outcomes, seqs):
        ok = o.decision == sc.expected
        all_ok &= ok
        colour = DECISION_COLOURS.get(o.decision, "red")
        radar = "skipped" if o.radar is None else f"{o.radar.model} {o.radar.confidence or 0:.0%}"
        reg = o.evidence.registry
        table.add_row(str(seq), sc.name, reg.model or reg.status, radar,
                      f"[{colour}]{o.decision}[/]" + ("" if ok else " [yellow](unexpected)[/]"),
                      ", ".join(o.reasons))
    print_table(table, console)
    console.print(f"returns in {out}; inspect one with `authn check {scenes[0][1]}`; "
                  f"audit with `authn audit verify`.  ({time.perf_counter() - t0:.1f} s)")
    raise typer.Exit(0 if all_ok else 1)
