"""`authn bench`: how often the decision is right, and how long it takes."""

from __future__ import annotations

import json

import typer

from authn.cli import app


@app.command()
def bench(
    preset: list[str] = typer.Option(["paper", "wide"], "--preset", help="Preset(s) to run (repeatable)."),
    n: int = typer.Option(100, "--n", min=1, help="Scenes per category and preset."),
    seed: int = typer.Option(7, "--seed", help="Seed of the scene draws."),
    quick: bool = typer.Option(False, "--quick", help="CI-sized run: 12 scenes per category, paper preset."),
    with_latency: bool = typer.Option(True, "--latency/--no-latency", help="Also time cold and batch checks."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """End-to-end decision accuracy on simulated claims (SNR 10-30 dB, random geometry)
    and check latency (cold process and batch mode).

    Categories: genuine claims (must be accepted), type spoofs between the shipped
    profiles, position spoofs of 100-300 m along the line of sight, unregistered
    and revoked serials (must be rejected, the latter two with the radar skipped).

    Example: authn bench --preset paper --n 200 --json
    """
    from rich.console import Console
    from rich.progress import Progress
    from rich.table import Table

    from authn.bench import CATEGORIES, latency, run_decisions, summarise
    from signatures.radar import get_preset

    if quick:
        preset, n = ["paper"], 12
    for p in preset:
        get_preset(p)
    with Progress(transient=True, disable=as_json) as progress:
        task = progress.add_task("checking simulated claims", total=len(preset) * len(CATEGORIES) * n)
        rows = run_decisions(tuple(preset), n, seed, progress=lambda k: progress.advance(task, k))
        lat = {p: latency(p, 5 if quick else 20, seed) for p in preset} if with_latency else {}
    report = {"decisions": summarise(rows), "latency_ms": lat, "n_per_category": n, "seed": seed}
    if as_json:
        typer.echo(json.dumps(report, indent=2))
        return
    table = Table(title=f"end-to-end decisions ({n} scenes per category, SNR 10-30 dB)")
    for col in ("preset", "category", "expected", "correct", "radar skipped", "median check"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(r.preset, r.category, "accept" if r.category == "genuine" else "reject",
                      f"{r.rate:.1%}", f"{r.radar_skipped / r.n:.0%}", f"{r.median_ms:.1f} ms")
    console = Console()
    console.print(table)
    for p, d in lat.items():
        console.print(f"{p}: cold `authn check` process {d['cold_process_ms']:.0f} ms (median of 5); "
                      f"in batch mode {d['batch_ms_per_check']:.1f} ms per check (median)")
