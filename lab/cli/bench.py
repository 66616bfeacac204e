"""`authn bench`: how often the decision is right, and how long it takes (plugged into `authn`
through the `authn.plugins` entry point of lab/pyproject.toml). One function per mode: the
default run (`_measure_all`, then JSON or tables), `--stress`, `--batch`, `--track`,
`--enrolment`, `--worlds-only`."""

from __future__ import annotations

import functools
import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress

    from lab.bench.worlds import Trial


@contextmanager
def _workers_end_on_stop() -> Iterator[None]:
    """SIGINT and SIGTERM stop the bench at once: every worker process is killed, then the
    stop is raised (`authn.cli.signals.interrupted`: exit 130 or 143) and unwinds the pools,
    which no longer wait for work in flight. A worker forked while this handler is installed
    inherits it: there Ctrl-C (sent to the whole process group) is left to the parent, which
    ends the worker, and SIGTERM (a pool ending its workers) ends it as by default."""
    import multiprocessing
    import os
    import signal

    from authn.cli.signals import handled, interrupted

    parent = os.getpid()

    def handler(signum: int, _frame: object) -> None:
        if os.getpid() != parent:
            if signum == signal.SIGTERM:
                signal.signal(signum, signal.SIG_DFL)
                os.kill(os.getpid(), signum)
            return
        for child in multiprocessing.active_children():
            child.kill()
        raise interrupted(signum)

    with handled(handler):
        yield


def _stoppable(command: Callable[..., None]) -> Callable[..., None]:
    """`command` run under `_workers_end_on_stop` (typer reads the wrapped signature)."""
    @functools.wraps(command)
    def run(*args: Any, **kwargs: Any) -> None:
        with _workers_end_on_stop():
            command(*args, **kwargs)

    return run


def _progress() -> "Progress":
    """The bench's progress bar: what runs, done of total, elapsed and an estimate of the time
    left; on stderr and only on a terminal, as `authn check`'s batch (stdout keeps the report)."""
    import sys

    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn,
                               TimeRemainingColumn)

    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    TextColumn("left"), TimeRemainingColumn(), transient=True, console=Console(stderr=True),
                    disable=not sys.stderr.isatty())


@_stoppable
def bench(
    preset: list[str] = typer.Option(["paper", "wide"], "--preset", show_default=False,
                                     help="Preset(s); default paper, wide."),
    n: int = typer.Option(100, "--n", min=1, show_default=False, help="Scenes per category (100)."),
    seed: int = typer.Option(7, "--seed", show_default=False, help="Seed of the scenes (7)."),
    seeds: int = typer.Option(1, "--seeds", min=1, show_default=False, help="Pool claims over N seeds."),
    quick: bool = typer.Option(False, "--quick", help="CI-sized: 12 per category, paper."),
    no_latency: bool = typer.Option(False, "--no-latency", help="Skip timing cold and batch checks."),
    stress: bool = typer.Option(False, "--stress", help="Only the numerical stress suite."),
    plot_dir: Path | None = typer.Option(None, "--plot", help="Write the plots (PNG) here."),
    world: str | None = typer.Option(None, "--world", help="training, heldout or both."),
    snr: list[float] = typer.Option([0.0, 10.0], "--snr", show_default=False, help="SNR rows, dB (0 and 10)."),
    worlds_only: bool = typer.Option(False, "--worlds-only", help="Only the identity claims."),
    batch: bool = typer.Option(False, "--batch", help="Only the batch-mode figures."),
    track: bool = typer.Option(False, "--track", help="Only the track rows."),
    enrolment: int | None = typer.Option(None, "--enrolment", min=5, help="Only site enrolment, N each."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Benchmark decisions and speed on simulated claims: accuracy, latency, stages, run time.

    On 2 cores --quick takes about 2.5 min, the default run tens of minutes. A progress bar
    with an estimate runs on stderr (a terminal only); Ctrl-C or SIGTERM stops within 2 s,
    workers ended (exit 130 or 143). The options by group: docs/benchmarks.md.

    Example: authn bench --quick
    """
    import registry.urls
    from lab.bench.worlds import WORLD_CATEGORIES, world_choice
    from signatures.radar import get_preset

    registry.urls.created_notice = None  # the bench's own temporary databases are not news
    if quick:
        preset, n = ["paper"], 12
    presets, snrs = tuple(preset), tuple(snr)
    worlds = world_choice(world or ("training" if quick else "both"))
    for p in presets:
        get_preset(p)
    if stress:
        _stress(presets, quick, as_json)
    elif batch:
        _batch(presets, quick, seed, plot_dir, as_json)
    elif track:
        _track(presets, snrs, n, seed, as_json, world_choice(world or "training"))
    elif enrolment is not None:
        _enrolment(enrolment, snrs, n, seed, as_json, world_choice(world or "heldout"))
    elif worlds_only:
        n_claims = len(presets) * len(snrs) * len(WORLD_CATEGORIES) * n * len(worlds)
        _worlds(presets, worlds, snrs, n, tuple(range(seed, seed + seeds)), n_claims * seeds, plot_dir, as_json)
    else:
        run = _measure_all(presets, worlds, snrs, n, seed, quick, no_latency)
        if plot_dir is not None:
            _plot_all(run, plot_dir)
        if as_json:
            typer.echo(json.dumps(_report(run), indent=2))
        else:
            _print_all(run)


@dataclass
class FullRun:
    """Everything the default run measures (`bench` without a mode option)."""

    presets: tuple[str, ...]
    n: int
    seed: int
    cold_repeats: int
    rows: list
    trials: list
    latency: dict
    stages: dict
    floor: dict
    dwell_floors: dict
    grid: dict
    imports: dict
    throughput: dict


def _measure_all(presets: tuple[str, ...], worlds: tuple[str, ...], snrs: tuple[float, ...], n: int, seed: int,
                 quick: bool, no_latency: bool) -> FullRun:
    """The default run: decisions per category, identity claims in each world, latency, stages,
    the FFT floor, run time against error, imports and throughput."""
    from lab.bench import pareto, perf
    from lab.bench.decisions import CATEGORIES, latency, run_decisions
    from lab.bench.variants import DWELL_DIVISORS
    from lab.bench.worlds import WORLD_CATEGORIES, run_worlds

    n_claims = len(presets) * len(snrs) * len(WORLD_CATEGORIES) * n * len(worlds)
    cold_repeats = 3 if quick else 11
    with _progress() as progress:
        task = progress.add_task("checking simulated claims", total=len(presets) * len(CATEGORIES) * n + n_claims)
        rows = run_decisions(presets, n, seed, progress=lambda k: progress.advance(task, k))
        progress.update(task, description="identity claims in " + " and ".join(worlds))
        trials = run_worlds(presets, worlds, n, seed, snrs, progress=lambda k: progress.advance(task, k))
        progress.remove_task(task)  # the timings below have no count to estimate from
        task = progress.add_task("timing checks", total=None)
        lat = {p: latency(p, 5 if quick else 20, seed, cold_repeats) for p in presets} if not no_latency else {}
        progress.update(task, description="timing stages")
        stages = {p: perf.stage_table(p, 14 if quick else 70, seed) for p in presets}
        floor = {p: perf.fft_floor(p) for p in presets}
        dwell_floors = {p: {f"1/{d}": perf.fft_floor(p, dwell_divisor=d)["fft_ms"] for d in DWELL_DIVISORS}
                        for p in presets}
        progress.update(task, description="run time against error")
        grid = {p: pareto.run(p, per_class=4 if quick else 25, seed=seed, n_train=300 if quick else 3000)
                for p in presets}
        progress.update(task, description="timing imports and throughput")
        imports = perf.import_costs(1 if quick else 3)
        tput = {p: perf.throughput(p, 20 if quick else 100, seed) for p in presets}
    return FullRun(presets, n, seed, cold_repeats, rows, trials, lat, stages, floor, dwell_floors, grid, imports,
                   tput)


def _near_floor(run: FullRun) -> dict:
    """Per preset, the front points within 3x of the FFT floor with macro F1 >= 0.95 at 10 dB."""
    from lab.bench import pareto

    return {p: pareto.near_floor(pts, run.floor[p]["fft_ms"]) for p, pts in run.grid.items()}


def _plot_all(run: FullRun, plot_dir: Path) -> None:
    """Error against run time per preset, and the two-world figures, as PNG in `plot_dir`."""
    from lab.bench import pareto
    from lab.bench.worlds import plot_worlds

    plot_dir.mkdir(parents=True, exist_ok=True)
    for p, pts in run.grid.items():
        pareto.plot(pts, (0.0, 10.0, 20.0), plot_dir / f"error-vs-time-{p}.png", run.floor[p]["fft_ms"])
    plot_worlds(run.trials, plot_dir)


def _report(run: FullRun) -> dict:
    """The default run as one JSON object (`--json`)."""
    from lab.bench.decisions import drip_cost, summarise
    from lab.bench.worlds import summarise_worlds

    return {"decisions": summarise(run.rows), "drip_verification_ms": drip_cost(run.rows), "latency_ms": run.latency,
            "stages": run.stages, "fft_floor": run.floor, "fft_floor_of_dwell_part_ms": run.dwell_floors,
            "pareto": {p: [pt.__dict__ for pt in pts] for p, pts in run.grid.items()},
            "near_fft_floor": {p: [q.name for q in pts] for p, pts in _near_floor(run).items()},
            "imports_ms": run.imports, "throughput_per_s": run.throughput, "n_per_category": run.n,
            "seed": run.seed, "worlds": summarise_worlds(run.trials)}


def _print_all(run: FullRun) -> None:
    """The default run as tables and lines on stdout."""
    from rich.console import Console

    from lab.bench.decisions import EXPECTED
    from lab.bench.tables import decision_table, imports_table

    console = Console()
    console.print(decision_table(run.rows, run.n, EXPECTED))
    _print_worlds(console, run.trials)
    _print_drip(console, run.rows)
    _print_latency(console, run.latency, run.cold_repeats)
    _print_stages(console, run)
    _print_pareto(console, run)
    console.print(imports_table(run.imports))


def _print_drip(console: "Console", rows: list) -> None:
    """What DRIP verification costs a check, and whether each DRIP rejection names its reason."""
    from lab.bench.decisions import DRIP_REASONS, drip_cost

    for p, d in drip_cost(rows).items():
        console.print(f"{p}: DRIP verification, median of the check's remote_id_auth stage:")
        console.print(f"  signed {d['signed_valid_ms']:.3f} ms, unsigned {d['unsigned_ms']:.3f} ms: "
                      f"+{d['signed_minus_unsigned_ms']:.3f} ms ({d['signed_valid_n']} and {d['unsigned_n']} checks)")
        console.print(f"  forged or replayed {d['signed_rejected_ms']:.3f} ms ({d['signed_rejected_n']} checks)")
    drip_rows = [r for r in rows if r.category in DRIP_REASONS]
    missing = [f"{r.preset}/{r.category} {r.reason_missing}" for r in drip_rows if r.reason_missing]
    console.print(f"  DRIP rejections with their own reason: {sum(r.n - r.reason_missing for r in drip_rows)} of "
                  f"{sum(r.n for r in drip_rows)}" + ("" if not missing else "; missing in " + ", ".join(missing)))


def _print_latency(console: "Console", lat: dict, cold_repeats: int) -> None:
    """A cold check process against `import numpy`, batch mode, and registry-only rejections."""
    for p, d in lat.items():
        console.print(f"{p}: cold `authn check` process {d['cold_process_ms']:.0f} ms = "
                      f"{d['cold_vs_import_numpy']:.2f}x `python -c 'import numpy'` ({d['import_numpy_ms']:.0f} ms, "
                      f"interleaved, medians of {cold_repeats}); in batch mode {d['batch_ms_per_check']:.1f} ms "
                      "per check")
        console.print(f"  registry-only rejection: cold process {d['cold_registry_only_ms']:.0f} ms; after start-up "
                      f"{d['first_registry_only_ms']:.1f} ms against {d['first_check_ms']:.1f} ms for a full first "
                      f"check = {d['first_registry_only_vs_full']:.1%}")


def _print_stages(console: "Console", run: FullRun) -> None:
    """Per preset: the stage table, the radar stage against the FFT floor, skips, throughput."""
    from lab.bench.tables import stage_table

    for p in run.presets:
        st, fl = run.stages[p], run.floor[p]
        console.print(stage_table(p, st, fl))
        radar_ms = st["stage_median_ms"].get("radar_features", float("nan"))
        console.print(f"  FFTs of one gated check: {fl['fft_mflop']:.2f} MFLOP at {fl['gflops']:.1f} GFLOP/s; "
                      f"radar_features is {radar_ms / fl['fft_ms']:.1f}x the FFT floor")
        share = st["skip_share"].get("radar_features", 0.0)
        console.print(f"  radar stage skipped in {share:.0%} of checks, saving "
                      f"{st['radar_time_saved_per_skip_ms']:.1f} ms each; registry-only check "
                      f"{st['registry_only_check_ms']:.1f} ms = {st['registry_only_vs_full']:.0%} of a full "
                      f"check ({st['full_check_ms']:.1f} ms)")
        tp = run.throughput[p]
        console.print(f"  throughput: {tp['1_worker']:.0f} returns/s with 1 worker, "
                      f"{tp['2_worker']:.0f} with 2 workers")


def _print_pareto(console: "Console", run: FullRun) -> None:
    """Per preset: run time against error, the points near the FFT floor, the partial-dwell floors."""
    from lab.bench.tables import pareto_table

    near = _near_floor(run)
    for p, pts in run.grid.items():
        fl = run.floor[p]["fft_ms"]
        console.print(pareto_table(p, pts, fl, (0.0, 10.0, 20.0)))
        console.print(f"  front points within 3x of the FFT floor ({fl:.2f} ms) with macro F1 >= 0.95 at 10 dB: "
                      + (", ".join(f"{q.name} ({q.ms_per_return / fl:.1f}x)" for q in near[p]) or "none"))
        console.print("  FFT floor of just the first part of the dwell (what those configurations transform): "
                      + ", ".join(f"{k} {v:.2f} ms" for k, v in run.dwell_floors[p].items()))


def _track(presets: tuple[str, ...], snrs: tuple[float, ...], n: int, seed: int, as_json: bool,
           worlds: tuple[str, ...] = ("training",)) -> None:
    """Only the track rows (`--track`, in each of `--world`, default training): dependence of
    dwell LLRs, dwells per decision."""
    from rich.console import Console
    from rich.table import Table

    from lab.bench.track import dependence, run_tracks, summarise_tracks

    with _progress() as progress:
        task = progress.add_task("simulated tracks", total=len(worlds) * len(presets) * len(snrs) * 2 * (n + 5 * n))
        step = lambda k: progress.advance(task, k)  # noqa: E731
        dep = [r for w in worlds for p in presets for s in snrs
               for r in dependence(p, n, 5, s, seed, progress=step, world=w)]
        rows = summarise_tracks([t for w in worlds for p in presets
                                 for t in run_tracks(p, snrs, n, 10, seed, progress=step, world=w)])
    if as_json:
        typer.echo(json.dumps({"dependence": [d.to_json() for d in dep], "tracks": rows, "n": n, "seed": seed},
                              indent=2))
        return
    console = Console()
    t = Table(title="dwell LLR correlation (ICC within one scene of a flown/claimed pair; Pearson of consecutive "
                    "dwells and of dwells of neighbouring scenes)")
    for col in ("preset", "world", "SNR dB", "claims", "ICC", "ICC pooled", "within", "between", "mean LLR"):
        t.add_column(col, justify="right")
    for d in dep:
        t.add_row(d.preset, d.world, f"{d.snr_db:g}", d.category, f"{d.icc:.3f}", f"{d.icc_pooled:.3f}",
                  f"{d.within:.3f}", f"{d.between:.3f}", f"{d.mean_llr:+.2f}")
    console.print(t)
    t = Table(title="track decisions (sequential test, at most 10 dwells)")
    for col in ("preset", "world", "SNR dB", "claims", "tracks", "right", "inconclusive", "median dwells",
                "mean dwells"):
        t.add_column(col, justify="right")
    for r in rows:
        t.add_row(r["preset"], r["world"], f"{r['snr_db']:g}", r["category"], str(r["tracks"]), f"{r['right']:.1%}",
                  f"{r['inconclusive']:.1%}", f"{r['median_dwells']:g}", f"{r['mean_dwells']:.2f}")
    console.print(t)


def _enrolment(size: int, snrs: tuple[float, ...], n: int, seed: int, as_json: bool, worlds: tuple[str, ...]) -> None:
    """Only the site-enrolment rows (`--enrolment N`): tracks and single dwells per category,
    per (flown, claimed) pair, and the card's pairwise errors, in each world."""
    import sys

    from rich.console import Console

    from lab.bench.enrolment import pair_table, run_tracks, track_table

    err = Console(stderr=True)
    docs = [run_tracks((size,), n, snrs, w, seed, 1500, log=lambda m: err.print(m) if not as_json else None)
            for w in worlds]
    if as_json:
        typer.echo(json.dumps(docs, indent=2))
        return
    for doc in docs:
        e = doc["enrolments"][size]
        print(f"\n{doc['world']} world, {size} enrolment recordings per airframe; tracks (first dwells alone):")
        print(track_table(doc))
        print("\ncard's cross-validated pairwise false accepts: single dwell / tracks of "
              f"{e['tracks']['dwells']} dwells")
        for pair, sd in e["pairwise"].items():
            tr = e["pairwise_tracks"][pair]
            print(f"  {pair}: {sd['false_accept_rate']:.1%} / "
                  f"{'n/a' if not tr or tr['false_accept_rate'] is None else format(tr['false_accept_rate'], '.1%')}")
        print("\nper pair:")
        print(pair_table(doc))
    sys.stdout.flush()


def _batch(presets: tuple[str, ...], quick: bool, seed: int, plot_dir: Path | None, as_json: bool) -> None:
    """Only the batch-mode figures (`--batch`)."""
    from rich.console import Console

    from lab.bench import batch
    from lab.bench.tables import batch_table

    sizes = (1, 8, 64) if quick else batch.SIZES
    report: dict[str, dict[str, object]] = {}
    with _progress() as progress:
        task = progress.add_task("batch mode", total=3 * len(presets))
        for p in presets:
            progress.update(task, description=f"{p}: per-return time against batch size")
            curve = batch.curve(p, sizes, distinct=10 if quick else 64, seed=seed, budget_s=5.0 if quick else 60.0)
            progress.advance(task)
            progress.update(task, description=f"{p}: accuracy, single against batched")
            acc = batch.accuracy(p, per_class=2 if quick else 20, seed=seed)
            progress.advance(task)
            progress.update(task, description=f"{p}: registry-only rejections against the I/O floor")
            reg = batch.registry_only(p, n=20 if quick else 200, seed=seed)
            progress.advance(task)
            report[p] = {"curve": curve, "accuracy": acc, "registry_only": reg}
    if plot_dir is not None:
        plot_dir.mkdir(parents=True, exist_ok=True)
        batch.plot({p: r["curve"] for p, r in report.items()}, plot_dir / "batch-size.png")
    if as_json:
        typer.echo(json.dumps(report, indent=2))
        return
    Console().print(batch_table(report))


def _worlds(presets: tuple[str, ...], worlds: tuple[str, ...], snrs: tuple[float, ...], n: int,
            seeds: tuple[int, ...], total: int, plot_dir: Path | None, as_json: bool) -> None:
    """Only the identity claims in the chosen worlds (`--worlds-only`), pooled over `seeds`."""
    from rich.console import Console

    from lab.bench.worlds import plot_worlds, run_worlds, summarise_worlds

    with _progress() as progress:
        task = progress.add_task("identity claims in " + " and ".join(worlds), total=total)
        trials = [t for seed in seeds
                  for t in run_worlds(presets, worlds, n, seed, snrs, progress=lambda k: progress.advance(task, k))]
    if plot_dir is not None:
        plot_dir.mkdir(parents=True, exist_ok=True)
        plot_worlds(trials, plot_dir)
    if as_json:
        doc = {"worlds": summarise_worlds(trials), "n_per_category": n * len(seeds), "seed": seeds[0]}
        if len(seeds) > 1:
            doc["seeds"] = list(seeds)
        typer.echo(json.dumps(doc, indent=2))
        return
    _print_worlds(Console(), trials)


def _print_worlds(console: "Console", trials: "list[Trial]") -> None:
    """The two-world tables, then each cell's wrong decisions by reason."""
    from collections import Counter

    from lab.bench.tables import eer_table, evidence_table, worlds_table

    console.print(worlds_table(trials))
    console.print(evidence_table(trials))
    console.print(eer_table(trials))
    wrong: dict[tuple, Counter] = {}
    for t in trials:
        if not t.correct:
            wrong.setdefault((t.world, t.preset, t.snr_db, t.category), Counter())[",".join(t.reasons)] += 1
    for (w, p, s, c), reasons in wrong.items():
        console.print(f"  {w} {p} {s:g} dB {c.replace('_', ' ')} wrong: "
                      + ", ".join(f"{k} {v}" for k, v in reasons.most_common()), markup=False)


def _stress(presets: tuple[str, ...], quick: bool, as_json: bool) -> None:
    """Only the numerical stress suite (`--stress`): exit 1 unless it is clean."""
    from rich.console import Console
    from rich.table import Table

    from lab.bench.stress import is_clean, run

    report = run(presets, quick=quick)
    doc = report.as_dict()
    if as_json:
        typer.echo(json.dumps(doc, indent=2))
    else:
        table = Table(title=f"numerical stress suite ({doc['cases']} cases, presets {', '.join(presets)})")
        table.add_column("check")
        table.add_column("count", justify="right")
        table.add_column("must be", justify="right")
        for key, must in (("crashes", "0"), ("nonfinite_features", "0"), ("scale_dependent_decisions", "0"),
                          ("nan_inf_not_refused", "0"), ("specific_errors", "-"), ("fft64_compared", "-"),
                          ("fft64_cases_above_rtol", "-"), ("fft64_label_changes", "-")):
            table.add_row(key.replace("_", " "), str(doc[key]), must)
        console = Console()
        console.print(table)
        console.print(f"features from float32 transforms against float64 ones: largest relative deviation "
                      f"{doc['fft64_max_rel_deviation']:.2e} (median over cases "
                      f"{doc['fft64_median_max_rel_deviation']:.2e}; relative to max(|float64|, 1))")
        for group in ("crashes", "nonfinite", "scale_decision_changes", "specific_errors", "fft64_deviations",
                      "fft64_label_changes"):
            for line in doc["details"][group]:
                console.print(f"  {group}: {line}", markup=False)
    raise typer.Exit(0 if is_clean(report) else 1)
