"""`authn bench`: how often the decision is right, and how long it takes."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import typer

if TYPE_CHECKING:
    from rich.console import Console

    from lab.bench.worlds import Trial


def bench(
    preset: list[str] = typer.Option(["paper", "wide"], "--preset", help="Preset(s) to run (repeatable)."),
    n: int = typer.Option(100, "--n", min=1, help="Scenes per category and preset."),
    seed: int = typer.Option(7, "--seed", help="Seed of the scene draws."),
    seeds: int = typer.Option(1, "--seeds", min=1, help="Identity claims over this many consecutive seeds from --seed, "
                              "pooled (issue protocol: 10 seeds x 3 airframes x 100 claims: --seeds 10 --n 100)."),
    quick: bool = typer.Option(False, "--quick", help="CI-sized run: 12 scenes per category, paper preset."),
    with_latency: bool = typer.Option(True, "--latency/--no-latency", help="Also time cold and batch checks."),
    stress: bool = typer.Option(False, "--stress",
                                help="Run the numerical stress suite instead (exit 1 unless clean)."),
    plot_dir: Path | None = typer.Option(None, "--plot", help="Write the error-versus-time and DET plots (PNG) here."),
    world: str | None = typer.Option(None, "--world", help="Worlds of the identity-claim rows: training, heldout or "
                                     "both (default both; training with --quick)."),
    snr: list[float] = typer.Option([0.0, 10.0], "--snr", help="SNR rows (dB) of the identity claims (repeatable)."),
    worlds_only: bool = typer.Option(False, "--worlds-only", help="Run only the identity claims in the worlds."),
    batch: bool = typer.Option(False, "--batch", help="Run only the batch-mode figures: per-return time against "
                               "batch size beside the FFT floor, accuracy against one return at a time, "
                               "registry-only rejections against the I/O floor."),
    track: bool = typer.Option(False, "--track", help="Run only the track rows: the correlation of dwell LLRs "
                               "within and between simulated scenes, and dwells per track decision against --snr "
                               "(docs/tracks.md)."),
    enrolment: int | None = typer.Option(None, "--enrolment", min=5, help="Run only the site-enrolment rows: enrol "
                                         "this many recordings per airframe (mixed SNR 0-20 dB), then --n tracks per "
                                         "category and --snr, with their first dwells alone beside, and per-pair rows "
                                         "(in each of --world, default heldout; docs/enrolment.md)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Benchmark decisions and speed: accuracy, latency, stages, error vs time, throughput.

    Decision accuracy on simulated claims (SNR 10-30 dB, random geometry); check
    latency (cold process and batch mode); per-stage medians beside the FFT floor;
    run time against error over pipeline configurations (Pareto front); import costs;
    skip share; throughput with 1 and 2 workers. With --stress: the numerical stress
    suite (IQ scaled 1e-30..1e30, ADC types, degenerate cubes, NaN/Inf, clipping, odd
    shapes, SNR -40..+80 dB, extreme geometry).

    Categories: genuine claims (right when accepted; one unsigned dwell is
    inconclusive at the default error targets), type spoofs between the shipped
    profiles, position spoofs of 100-300 m along the line of sight, unregistered
    and revoked serials (right when not accepted, the latter two with the radar
    skipped); the share inconclusive is reported beside.
    Signed Remote ID (IETF DRIP) against identities registered with a key: a genuine
    signed flight (accepted), an unsigned claim by a drone of the same type, a forged
    signature (another key, the victim's DET) and a day-old replayed one (rejected),
    with the verification's cost per check (signed against unsigned).

    Identity claims in two worlds: genuine claims, type spoofs and airframes never
    trained on (octocopter, 5-inch racer, coaxial X8, tricopter) claiming a registered
    serial, at each --snr, rendered by the training simulator and by the held-out model
    (lab.heldout, a different signal model), the same scenes in both; right
    decisions side by side, and the verification score's equal error rate and DET
    curves (det-<preset>.png with --plot).

    Example: authn bench --preset paper --n 200 --json

    Example: authn bench --stress --quick

    Batch mode (--batch): batched features + classifier per return at batch sizes 1 to 1024
    beside one return at a time and the FFT floor (batch-size.png with --plot), macro F1
    of both on the same returns, and registry-only rejections in batch mode against
    the I/O floor (open + validate + hash + one Cedar decision).

    Example: authn bench --worlds-only --world both --n 100 --plot docs/figures

    Example: authn bench --worlds-only --world both --n 100 --seeds 10 --preset paper

    Example: authn bench --batch --plot docs/figures

    Tracks (--track): --n genuine and type-spoof tracks of 10 dwells per --snr, each decided by the
    sequential test of `authn check --track`: right decisions and median dwells per decision; and
    the intra-track correlation of the dwell LLRs the test discounts (5 dwells of --n scenes).

    Example: authn bench --track --preset paper --n 40 --snr 0 --snr 5 --snr 10 --snr 20

    Site enrolment (--enrolment N, paper preset): a site bundle enrolled from N recordings per
    airframe, then tracks of up to 8 dwells (genuine, type spoof, unseen airframe), decided with the
    shipped and the site bundle: rows per category and per (flown, claimed) pair, and the card's
    pairwise errors of single dwells and of tracks (python -m lab.bench.enrolment --track).

    Example: authn bench --enrolment 30 --n 50 --snr 0 --snr 10 --world heldout
    """
    import registry.urls
    from rich.console import Console
    from rich.progress import Progress

    registry.urls.created_notice = None  # the bench's own temporary databases are not news

    from lab.bench.decisions import (CATEGORIES, DRIP_REASONS, EXPECTED, drip_cost, latency, run_decisions,
                                       summarise)
    from lab.bench.tables import decision_table, imports_table, pareto_table, stage_table
    from lab.bench.worlds import WORLD_CATEGORIES, world_choice
    from signatures.radar import get_preset

    if quick:
        preset, n = ["paper"], 12
    worlds = world_choice(world or ("training" if quick else "both"))
    for p in preset:
        get_preset(p)
    if stress:
        _stress(tuple(preset), quick, as_json)
        return
    if batch:
        _batch(tuple(preset), quick, seed, plot_dir, as_json)
        return
    if track:
        _track(tuple(preset), tuple(snr), n, seed, as_json, world_choice(world or "training"))
        return
    if enrolment is not None:
        _enrolment(enrolment, tuple(snr), n, seed, as_json, world_choice(world or "heldout"))
        return
    n_claims = len(preset) * len(snr) * len(WORLD_CATEGORIES) * n * len(worlds)
    if worlds_only:
        _worlds(tuple(preset), worlds, tuple(snr), n, tuple(range(seed, seed + seeds)), n_claims * seeds, plot_dir,
                as_json)
        return
    from lab.bench import pareto, perf
    from lab.bench.variants import DWELL_DIVISORS
    from lab.bench.worlds import plot_worlds, run_worlds, summarise_worlds

    with Progress(transient=True, disable=as_json) as progress:
        task = progress.add_task("checking simulated claims", total=len(preset) * len(CATEGORIES) * n + n_claims)
        rows = run_decisions(tuple(preset), n, seed, progress=lambda k: progress.advance(task, k))
        progress.update(task, description="identity claims in " + " and ".join(worlds))
        trials = run_worlds(tuple(preset), worlds, n, seed, tuple(snr), progress=lambda k: progress.advance(task, k))
        cold_repeats = 3 if quick else 11
        lat = {p: latency(p, 5 if quick else 20, seed, cold_repeats) for p in preset} if with_latency else {}
        progress.update(task, description="timing stages")
        stages = {p: perf.stage_table(p, 14 if quick else 70, seed) for p in preset}
        floor = {p: perf.fft_floor(p) for p in preset}
        dwell_floors = {p: {f"1/{d}": perf.fft_floor(p, dwell_divisor=d)["fft_ms"] for d in DWELL_DIVISORS}
                        for p in preset}
        progress.update(task, description="run time against error")
        grid = {p: pareto.run(p, per_class=4 if quick else 25, seed=seed, n_train=300 if quick else 3000)
                for p in preset}
        progress.update(task, description="timing imports and throughput")
        imports = perf.import_costs(1 if quick else 3)
        tput = {p: perf.throughput(p, 20 if quick else 100, seed) for p in preset}
    near = {p: pareto.near_floor(pts, floor[p]["fft_ms"]) for p, pts in grid.items()}
    if plot_dir is not None:
        plot_dir.mkdir(parents=True, exist_ok=True)
        for p, pts in grid.items():
            pareto.plot(pts, (0.0, 10.0, 20.0), plot_dir / f"error-vs-time-{p}.png", floor[p]["fft_ms"])
        plot_worlds(trials, plot_dir)
    drip = drip_cost(rows)
    report = {"decisions": summarise(rows), "drip_verification_ms": drip, "latency_ms": lat, "stages": stages,
              "fft_floor": floor,
              "fft_floor_of_dwell_part_ms": dwell_floors,
              "pareto": {p: [pt.__dict__ for pt in pts] for p, pts in grid.items()},
              "near_fft_floor": {p: [q.name for q in pts] for p, pts in near.items()},
              "imports_ms": imports, "throughput_per_s": tput, "n_per_category": n, "seed": seed,
              "worlds": summarise_worlds(trials)}
    if as_json:
        typer.echo(json.dumps(report, indent=2))
        return
    console = Console()
    console.print(decision_table(rows, n, EXPECTED))
    _print_worlds(console, trials)
    for p, d in drip.items():
        console.print(f"{p}: DRIP verification, median of the check's remote_id_auth stage:")
        console.print(f"  signed {d['signed_valid_ms']:.3f} ms, unsigned {d['unsigned_ms']:.3f} ms: "
                      f"+{d['signed_minus_unsigned_ms']:.3f} ms ({d['signed_valid_n']} and {d['unsigned_n']} checks)")
        console.print(f"  forged or replayed {d['signed_rejected_ms']:.3f} ms ({d['signed_rejected_n']} checks)")
    drip_rows = [r for r in rows if r.category in DRIP_REASONS]
    missing = [f"{r.preset}/{r.category} {r.reason_missing}" for r in drip_rows if r.reason_missing]
    console.print(f"  DRIP rejections with their own reason: {sum(r.n - r.reason_missing for r in drip_rows)} of "
                  f"{sum(r.n for r in drip_rows)}" + ("" if not missing else "; missing in " + ", ".join(missing)))
    for p, d in lat.items():
        console.print(f"{p}: cold `authn check` process {d['cold_process_ms']:.0f} ms = "
                      f"{d['cold_vs_import_numpy']:.2f}x `python -c 'import numpy'` ({d['import_numpy_ms']:.0f} ms, "
                      f"interleaved, medians of {cold_repeats}); in batch mode {d['batch_ms_per_check']:.1f} ms "
                      "per check")
        console.print(f"  registry-only rejection: cold process {d['cold_registry_only_ms']:.0f} ms; after start-up "
                      f"{d['first_registry_only_ms']:.1f} ms against {d['first_check_ms']:.1f} ms for a full first "
                      f"check = {d['first_registry_only_vs_full']:.1%}")
    for p in preset:
        st, fl = stages[p], floor[p]
        console.print(stage_table(p, st, fl))
        radar_ms = st["stage_median_ms"].get("radar_features", float("nan"))
        console.print(f"  FFTs of one gated check: {fl['fft_mflop']:.2f} MFLOP at {fl['gflops']:.1f} GFLOP/s; "
                      f"radar_features is {radar_ms / fl['fft_ms']:.1f}x the FFT floor")
        share = st["skip_share"].get("radar_features", 0.0)
        console.print(f"  radar stage skipped in {share:.0%} of checks, saving "
                      f"{st['radar_time_saved_per_skip_ms']:.1f} ms each; registry-only check "
                      f"{st['registry_only_check_ms']:.1f} ms = {st['registry_only_vs_full']:.0%} of a full "
                      f"check ({st['full_check_ms']:.1f} ms)")
        tp = tput[p]
        console.print(f"  throughput: {tp['1_worker']:.0f} returns/s with 1 worker, "
                      f"{tp['2_worker']:.0f} with 2 workers")
    for p, pts in grid.items():
        fl = floor[p]["fft_ms"]
        console.print(pareto_table(p, pts, fl, (0.0, 10.0, 20.0)))
        console.print(f"  front points within 3x of the FFT floor ({fl:.2f} ms) with macro F1 >= 0.95 at 10 dB: "
                      + (", ".join(f"{q.name} ({q.ms_per_return / fl:.1f}x)" for q in near[p]) or "none"))
        console.print("  FFT floor of just the first part of the dwell (what those configurations transform): "
                      + ", ".join(f"{k} {v:.2f} ms" for k, v in dwell_floors[p].items()))
    console.print(imports_table(imports))


def _track(presets: tuple[str, ...], snrs: tuple[float, ...], n: int, seed: int, as_json: bool,
           worlds: tuple[str, ...] = ("training",)) -> None:
    """Only the track rows (`--track`, in each of `--world`, default training): dependence of
    dwell LLRs, dwells per decision."""
    from rich.console import Console
    from rich.progress import Progress
    from rich.table import Table

    from lab.bench.track import dependence, run_tracks, summarise_tracks

    with Progress(transient=True, disable=as_json) as progress:
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
    from rich.progress import Progress

    from lab.bench import batch
    from lab.bench.tables import batch_table

    sizes = (1, 8, 64) if quick else batch.SIZES
    report: dict[str, dict[str, object]] = {}
    with Progress(transient=True, disable=as_json) as progress:
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
    from rich.progress import Progress

    from lab.bench.worlds import plot_worlds, run_worlds, summarise_worlds

    with Progress(transient=True, disable=as_json) as progress:
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
