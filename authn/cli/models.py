"""`authn models train / enrol / use / list / evaluate`: build classifier bundles (for a shipped
preset or any waveform), adapt them to the site's radar from its recorded flights (site
enrolment, docs/classifiers.md), pick the active one, list them, and print the paper's metrics."""

from __future__ import annotations

import json
import time
from pathlib import Path

import typer


#: `models enrol --calibrate` and `--site-bands`: on, off, or auto (None: the enrolment decides: where
#: the site's scores say the calibration pays; site bands with one model).
CALIBRATE = {"auto": None, "on": True, "off": False}

models_app = typer.Typer(help="Train, enrol, list and evaluate the radar classifiers (kNN, RF, SVM, ensemble, CNN).",
                         no_args_is_help=True)


def _profiles(files: list[Path] | None, preset_default: bool = True):  # -> tuple[UavProfile, ...]
    from signatures.profiles import load_profiles, shipped_profiles

    out = dict(shipped_profiles()) if preset_default else {}
    for f in files or []:
        out.update(load_profiles(f))
    return tuple(out.values())


@models_app.command("train")
def train(
    preset: str | None = typer.Option(None, "--preset",
                                      help="Shipped radar preset: paper or wide (the default without --like "
                                           "or --radar-config)."),
    like: Path | None = typer.Option(None, "--like", help="Train for the waveform of this recorded-return file."),
    radar_config: Path | None = typer.Option(None, "--radar-config",
                                             help="Train for the waveform in this JSON file (docs/waveform.md)."),
    profiles: list[Path] | None = typer.Option(None, "--profiles",
                                               help="JSON file of extra UAV profiles to enrol (repeatable)."),
    samples: int | None = typer.Option(None, "--samples", min=50,
                                       help="Training returns (default by cube size: 8000 paper, 4000 wide)."),
    val_samples: int | None = typer.Option(None, "--val-samples", min=50,
                                           help="Validation returns (default: samples / 4)."),
    test_samples: int | None = typer.Option(None, "--test-samples", min=10,
                                            help="Held-out test returns per SNR (0, 10, 20 dB) measured into the card "
                                                 "(default: samples / 20, 50..300, with --like/--radar-config; "
                                                 "none with --preset)."),
    seed: int = typer.Option(0, "--seed", help="Training seed (datasets, forests, SVM, CNN)."),
    cnn: bool = typer.Option(False, "--cnn", help="Also train the RD-patch CNN (needs torch) and the cascade."),
    randomise: bool = typer.Option(False, "--randomise",
                                   help="Domain randomisation of the training scenes (docs/worlds.md)."),
    out: Path | None = typer.Option(None, "--out", help="Bundle folder (default: <models dir>/<waveform name>; "
                                                        "`authn models list` shows the models dir)."),
    overwrite_shipped: bool = typer.Option(False, "--overwrite-shipped",
                                           help="Let --out replace the shipped bundle of --preset (maintainers)."),
    workers: int = typer.Option(2, "--workers", min=1, max=64, help="Simulation worker processes."),
    cluster: str | None = typer.Option(None, "--cluster",
                                       help="Simulate the datasets as tasks on Dask workers instead: 'local' or a "
                                            "scheduler address (needs the cluster extra; docs/cluster.md)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object at the end (progress on stderr)."),
) -> None:
    """Simulate, train and export a model bundle (numpy arrays, ONNX files, model card).

    Example: authn models train --like my_radar_capture.h5

    Example (rebuild a shipped bundle): authn models train --preset paper --cnn --out signatures/models/paper \\
      --overwrite-shipped
    """
    from rich.console import Console

    from signatures.train.dataset import DatasetSpec, progress_note
    from signatures.train.eta import pace as timed_pace
    from signatures.train.eta import seconds as eta_seconds
    from signatures.sim.sampling import NuisanceDistribution
    from signatures.train.training import TrainConfig, default_samples, train_bundle

    wf = _waveform(preset, like, radar_config)
    folder = _bundle_folder(out, wf, overwrite_shipped)
    n = samples or default_samples(wf)
    known = _profiles(profiles)
    n_val = val_samples or max(n // 4, 50)
    n_test = test_samples if test_samples is not None else (0 if wf.shipped else min(max(n // 20, 50), 300))
    unknown = tuple(p for p in _invented() if p.slug not in {k.slug for k in known})
    cfg = TrainConfig(preset=wf, profiles=known, n_train=n, n_val=n_val, seed=seed, cnn=cnn, workers=workers,
                      unknown_profiles=unknown, n_unknown_val=max(n_val // 4, 20), n_test=n_test,
                      nuisance=NuisanceDistribution() if randomise else None)
    console = Console(stderr=as_json)  # with --json, stdout carries only the JSON object
    n_cal = 0 if randomise else n_val  # the temperature's randomised validation set (training randomised: val itself)
    total = (n + n_val + n_cal + cfg.n_unknown_val
             + len(cfg.test_snrs) * (n_test + (max(n_test // 2, 10) if n_test else 0)))
    pace = timed_pace(DatasetSpec(preset=wf, profiles=known, split="train", n=n, seed=seed), workers)
    eta = eta_seconds(total, pace)
    console.print(f"[bold]{wf.name}[/]: {wf.describe()}. Simulating {total} returns ({n} train, {n_val} validation"
                  + (f", {n_cal} randomised for calibration" if n_cal else "")
                  + (f", {n_test} test per SNR" if n_test else "") + f") at {pace.seconds_per_return * 1e3:.0f} ms "
                  f"each with {workers} workers (timed on {pace.timed} at once): about {eta / 60:.1f} min, plus "
                  "fitting (cached datasets are reused).")
    why = _why_slow(eta, total, n, pace)
    if why:
        console.print(why)
    t0 = time.perf_counter()
    with progress_note(f"{pace.seconds_per_return * 1e3:.0f} ms/return, about {eta / 60:.1f} min in all"
                       if why else ""):
        if cluster is None:
            card = train_bundle(cfg, folder, progress=not as_json)
        else:  # the engine is imported only here
            from authn.cluster.engine import training_on

            with training_on(cluster):
                card = train_bundle(cfg, folder, progress=not as_json)
    if as_json:
        typer.echo(json.dumps({"name": wf.name, "folder": str(folder), "waveform": wf.as_json(),
                               "seconds": round(time.perf_counter() - t0, 3), "metrics": card["metrics"]}, indent=2))
        return
    console.print(f"[bold]{wf.name}[/] bundle written to {folder} in {time.perf_counter() - t0:.0f} s")
    for name, m in card["metrics"]["validation"].items():
        console.print(f"  validation {name}: {m}")
    if "test" in card["metrics"]:
        _print_test(console, card)
    if not wf.shipped:
        console.print(f"`authn check` now picks it for files of this waveform (or: --model {folder})")
    elif not overwrite_shipped:
        console.print(f"the shipped {wf.name} bundle still serves {wf.name} files; this one: "
                      f"`authn check --model {folder}`")


#: A training run is said to be long (and why) from this many seconds on.
LONG_S = 60.0


def _why_slow(eta: float, total: int, n: int, pace) -> str:  # pace: signatures.train.eta.Pace
    """Why a training run takes over `LONG_S`: the simulation dominates (returns, pace, workers),
    and what shortens it; '' when it does not."""
    if eta < LONG_S:
        return ""
    return (f"over a minute: simulating the {total} returns dominates (each {pace.seconds_per_return * 1e3:.0f} ms of "
            f"wall time with {pace.workers} workers; fitting takes seconds); --samples sets the training returns "
            f"({n} now), --workers the processes, and a second run reads the cached datasets")


def _waveform(preset: str | None, like: Path | None, radar_config: Path | None):  # -> Preset
    """The waveform to train for, from exactly one of the three options."""
    from signatures.errors import SignaturesError
    from signatures.radar import get_preset, load_waveform, recording_waveform
    from signatures.recording import read_recording

    given = [name for name, v in (("--preset", preset), ("--like", like), ("--radar-config", radar_config)) if v]
    if len(given) > 1:
        raise SignaturesError(f"{' and '.join(given)}: give only one of --preset, --like, --radar-config")
    if like is None and radar_config is None:
        return get_preset(preset or "paper")
    source = like or radar_config
    wf = recording_waveform(read_recording(like)) if like else load_waveform(radar_config)
    if wf.shipped:
        raise SignaturesError(f"{source}: this is the shipped preset {wf.name!r}, whose classifier ships with authn "
                              f"(retrain it with --preset {wf.name})")
    return wf


def _bundle_folder(out: Path | None, wf, overwrite_shipped: bool) -> Path:
    """Where the bundle goes: never inside the installed package unless a maintainer replaces a
    shipped preset's bundle on purpose, never over a folder that is not a bundle."""
    from signatures.errors import SignaturesError
    from signatures.classify.inference import bundle_dir, models_dir

    folder = out or models_dir() / wf.name
    shipped_root = bundle_dir(wf.name).parent.resolve()
    target = folder.resolve()
    if target.is_relative_to(shipped_root):
        if not (wf.shipped and overwrite_shipped and target == bundle_dir(wf.name).resolve()):
            raise SignaturesError(f"--out {folder}: inside the shipped bundles ({shipped_root}); only "
                                  f"`--preset NAME --out {shipped_root}/NAME --overwrite-shipped` replaces one")
    elif overwrite_shipped:
        raise SignaturesError("--overwrite-shipped: only with --preset and --out naming that preset's shipped bundle")
    if folder.exists() and not (folder / "card.json").is_file() and (not folder.is_dir() or any(folder.iterdir())):
        raise SignaturesError(f"--out {folder}: exists and is not a model bundle (refusing to replace it)")
    return folder


def _print_test(console, card: dict) -> None:
    from rich import box
    from rich.table import Table

    test = card["metrics"]["test"]
    t = Table(title=f"held-out test, {test['n_per_snr']} returns per SNR: what `authn check` would conclude",
              box=box.SIMPLE_HEAD)
    for col in ("SNR", "accuracy", "macro F1", "own type", "other", "unknown", "false alarm", "unseen"):
        t.add_column(col, justify="right")
    for snr, r in sorted(test["per_snr"].items(), key=lambda kv: float(kv[0])):
        unseen = r.get("unknown_rejection")
        t.add_row(f"{snr} dB", *(f"{r[k]:.3f}" for k in ("accuracy", "macro_f1", "genuine_confirmed", "wrong_airframe",
                                                         "called_unknown", "false_alarm_rate")),
                  "-" if unseen is None else f"{unseen:.3f}")
    console.print(t)
    console.print("own type / other / unknown: known airframes labelled as themselves, as another enrolled "
                  "airframe, as unknown; false alarm: bird/none called an airframe; unseen: never-trained "
                  "airframes called unknown")


@models_app.command("list")
def list_models(
    as_json: bool = typer.Option(False, "--json", help="Print a JSON array with each bundle's exact waveform."),
) -> None:
    """Shipped and user model bundles: name, waveform, airframes, validation accuracy, the
    pairs of shipped profiles radar cannot separate (--json: every pair's measured separation
    per dwell and dwells to decide).

    With --json, each bundle's waveform carries the exact parameter values a file must match
    (within 1e-3 relative): the radar-configuration document `--radar-config` reads; but for the
    carrier, which may lie anywhere in `carrier_band_hz` (+-2.5 %: one bundle serves a radar
    that hops its carrier, docs/waveform.md "Carrier band").

    Example: authn models list --json
    """
    from rich import box
    from rich.table import Table

    from authn.cli.output import print_table
    from signatures.classify.inference import bundle_dir, models_dir, user_bundles
    from signatures.classify.modelcard import CARD_NAME
    from signatures.radar import PRESETS

    rows = [(name, "shipped", bundle_dir(name), json.loads((bundle_dir(name) / CARD_NAME).read_text()))
            for name in PRESETS if (bundle_dir(name) / CARD_NAME).is_file()]
    rows += [(folder.name, "site" if isinstance(card, dict) and "enrolment" in card else "user", folder, card)
             for folder, card in user_bundles()]
    docs = [_bundle_json(name, kind, folder, card) for name, kind, folder, card in rows]
    _mark_active(docs)
    if as_json:
        typer.echo(json.dumps(docs, indent=2))
        return
    t = Table(title=f"model bundles (user bundles in {models_dir()}; * = what `authn check` uses for its waveform)",
              title_justify="left", box=box.SIMPLE_HEAD)
    t.add_column("", no_wrap=True)
    for col in ("name", "kind"):
        t.add_column(col, no_wrap=True)  # identifiers: never split
    t.add_column("waveform", overflow="fold")
    t.add_column("airframes", overflow="fold")  # a comma-separated list: wraps between names
    t.add_column("val acc", justify="right", no_wrap=True)
    t.add_column("radar cannot separate", overflow="fold")
    for d in docs:
        wave = "unreadable card"
        if d["waveform"]:
            lo, hi = d["carrier_band_hz"]
            wave = f"{d['waveform']['description']}; carrier {lo / 1e9:.4g}-{hi / 1e9:.4g} GHz"
        acc = "" if d["validation_accuracy"] is None else f"{d['validation_accuracy']:.3f}"
        t.add_row("*" if d["active"] else "", d["name"], d["kind"], wave, ", ".join(d["airframes"]), acc,
                  ", ".join(d.get("radar_confusable", [])) if "separation" in d else "")
    print_table(t)


def _mark_active(docs: list[dict]) -> None:
    """`active`: the bundle `authn check` picks for its waveform. A site bundle when `active.json`
    names it; a shipped or trained bundle when no site bundle is active for its waveform (of
    trained ones, the first by name)."""
    from signatures.classify.inference import active_map

    active = active_map()
    taken: set[str] = set()
    order = sorted(docs, key=lambda d: (d["kind"] != "shipped", d["name"]))
    for d in order:
        key = d["waveform"]["key"] if d["waveform"] else None
        if d["kind"] == "site":
            d["active"] = key is not None and active.get(key) == d["name"]
        else:
            d["active"] = key is not None and key not in active and key not in taken
        if d["active"] and key is not None:
            taken.add(key)


def _bundle_json(name: str, kind: str, folder: Path, card) -> dict:
    """One bundle of `models list --json`: a broken card is listed with its error, not a stop."""
    from signatures.errors import SignaturesError
    from signatures.classify.carrier import carrier_band_hz
    from signatures.classify.inference import card_waveform
    from signatures.profiles import NON_UAV_CLASSES

    doc: dict = {"name": name, "kind": kind, "folder": str(folder), "waveform": None, "carrier_band_hz": None,
                 "airframes": [],
                 "validation_accuracy": None, "error": None, "active": False}
    try:
        wf = card_waveform(card)
        doc["waveform"] = {**wf.as_json(), "description": wf.describe(), "key": wf.key}
        doc["carrier_band_hz"] = list(carrier_band_hz(wf))
        doc["airframes"] = [c for c in card["classes"] if c not in NON_UAV_CLASSES]
        doc["validation_accuracy"] = float(card["metrics"]["validation"]["ensemble"]["accuracy"])
        sep = card.get("separation")
        if isinstance(sep, dict):  # a shipped card's measured pairs (docs/classifiers.md "Separation")
            doc["separation"] = sep
            doc["radar_confusable"] = sorted({"/".join(sorted((p["claimed"], p["against"])))
                                              for p in sep.get("pairs", []) if p.get("confusable")})
    except (SignaturesError, KeyError, TypeError, ValueError) as exc:
        doc["error"] = "unreadable card" + (f" ({exc})" if isinstance(exc, SignaturesError) else "")
    return doc


@models_app.command("evaluate")
def evaluate(
    preset: str = typer.Option("paper", "--preset", help="Shipped preset or user bundle name to evaluate."),
    model: Path | None = typer.Option(None, "--model", help="Bundle folder (default: the one --preset names)."),
    snr: str = typer.Option("-20,-15,-10,-5,0,5,10,20,30", "--snr", show_default=False,
                            help="Comma-separated SNRs, dB (default: -20, -15, -10, -5, 0, 5, 10, 20, 30)."),
    samples: int = typer.Option(500, "--samples", min=10, help="Test returns per SNR."),
    seed: int = typer.Option(1000, "--seed", help="Test seed (use one never used in training)."),
    unknown: Path | None = typer.Option(None, "--unknown-profiles",
                                        help="Profiles never trained on, for the open-set rate "
                                             "(default: the shipped invented quad and hexa)."),
    as_json: Path | None = typer.Option(None, "--json", help="Also write the full report as JSON here."),
    plot_dir: Path | None = typer.Option(None, "--plot", help="Write confusion-matrix and accuracy-vs-SNR PNGs here."),
    workers: int = typer.Option(2, "--workers", min=1, max=64, help="Simulation worker processes."),
) -> None:
    """Accuracy, macro F1, TP confidence, false alarm rate, time delay per model and SNR.

    Example: authn models evaluate --preset paper --snr 0,10,20 --json paper.json --plot plots/
    """
    from signatures.errors import SignaturesError
    from signatures.train.evaluate import evaluate as run_eval
    from signatures.train.evaluate import plot, write_json
    from signatures.classify.inference import load_classifier
    from signatures.profiles import load_profiles

    try:
        snrs = [float(s) for s in snr.split(",") if s.strip()]
    except ValueError:
        raise SignaturesError(f"--snr: expected comma-separated numbers, got {snr!r}") from None
    if not snrs:
        raise SignaturesError("--snr: give at least one SNR")
    clf = load_classifier(preset=None if model else preset, path=model)
    unknown_profiles = tuple(load_profiles(unknown).values()) if unknown else _invented()
    unknown_profiles = tuple(p for p in unknown_profiles if p.slug not in clf.classes)
    report = run_eval(clf, snrs, samples, seed, unknown_profiles, progress=True, workers=workers)
    _print(report)
    if as_json:
        write_json(report, as_json)
    if plot_dir:
        for p in plot(report, plot_dir):
            typer.echo(f"wrote {p}")


def _invented():  # -> tuple[UavProfile, ...]
    from signatures.profiles import DATA, parse_profiles

    text = (DATA / "openset_profiles.json").read_text(encoding="utf-8")
    return tuple(parse_profiles(json.loads(text), "openset_profiles.json").values())


def _print(report: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    snrs = sorted(report["per_snr"], key=float)
    models = list(report["per_snr"][snrs[0]])
    for metric in ("accuracy", "macro_f1", "tp_confidence", "false_alarm_rate"):
        t = Table(title=f"{metric} ({report['preset']} preset, {report['n_per_snr']} test returns per SNR)")
        t.add_column("model")
        for s in snrs:
            t.add_column(f"{s} dB", justify="right")
        for m in models:
            t.add_row(m, *(f"{report['per_snr'][s][m][metric]:.4f}" for s in snrs))
        console.print(t)
    if report["open_set"]:
        t = Table(title="open set: never-trained profiles called 'unknown'")
        t.add_column("SNR")
        t.add_column("unknown rate", justify="right")
        t.add_column("per profile")
        for s in sorted(report["open_set"], key=float):
            o = report["open_set"][s]
            t.add_row(f"{s} dB", f"{o['unknown_rate']:.3f}", json.dumps(o["per_profile"]))
        console.print(t)
    t = Table(title="latency per return, ms (median; features excluded / classification time delay)")
    t.add_column("model")
    t.add_column("model only", justify="right")
    t.add_column("with features", justify="right")
    for m, v in report["latency_ms"].items():
        t.add_row(m, f"{v:.3f}", f"{report['classification_time_delay_ms'][m]:.3f}")
    console.print(t)
    top = snrs[-1]
    cm = report["per_snr"][top].get("system", {}).get("confusion")
    if cm:
        t = Table(title=f"confusion, system (ensemble + open set), {top} dB")
        t.add_column("true \\ predicted")
        for c in cm["cols"]:
            t.add_column(c, justify="right")
        for r, row in zip(cm["rows"], cm["matrix"]):
            t.add_row(r, *(str(v) for v in row))
        console.print(t)


# --- site enrolment ------------------------------------------------------------------------

def _recording_files(paths: list[Path]) -> list[Path]:
    """The recordings named: files as given, directories' .h5/.hdf5/.npz files (recursively, sorted)."""
    from signatures.train.site_samples import EnrolError
    from signatures.recording import recordings_in

    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            out += recordings_in(p, recursive=True)
        elif p.is_file():
            out.append(p)
        else:
            raise EnrolError(f"{p}: no such file or directory")
    seen: dict[Path, Path] = {}
    for f in out:
        seen.setdefault(f.resolve(), f)
    if not seen:
        raise EnrolError(f"no recordings (.h5, .hdf5, .npz) in {', '.join(str(p) for p in paths)}")
    return list(seen.values())


def _labelled(files: list[Path], labels: Path | None, db) -> list[tuple[Path, str | None]]:
    """(file, model) for each recording: from LABELS.csv (every recording needs a row, and every
    row's file must be among the recordings), else None: from its Remote ID serial, later."""
    from signatures.train.site_samples import EnrolError, read_labels

    if labels is None:
        return [(f, None) for f in files]
    rows = dict(read_labels(labels))
    resolved = {f.resolve(): f for f in files}
    missing = [f for r, f in resolved.items() if r not in rows and r != labels.resolve()]
    if missing:
        raise EnrolError(f"{missing[0]}: no label in {labels} (every recording needs a file,model row)")
    extra = [r for r in rows if r not in resolved]
    if extra:
        raise EnrolError(f"{labels}: labels {extra[0]}, which is not among the recordings given")
    return [(f, rows[r]) for r, f in resolved.items()]


def _distinct(todo: list[tuple[Path, str | None]]) -> list[tuple[Path, str | None]]:
    """The recordings with every copy of one (by the SHA-256 of its bytes) after the first left
    out: a copy is the same flight, never a second one. The same bytes under two labels are bad
    input."""
    from core.digest import file_sha256
    from signatures.train.site_samples import EnrolError

    first: dict[str, tuple[Path, str | None]] = {}
    kept = []
    for f, model in todo:
        digest = file_sha256(f)
        if digest not in first:
            first[digest] = (f, model)
            kept.append((f, model))
        elif first[digest][1] != model:
            raise EnrolError(f"{first[digest][0]} and {f} are the same recording (SHA-256 {digest[:12]}...) "
                             f"labelled {first[digest][1]} and {model}")
    return kept


def _site_samples(todo: list[tuple[Path, str | None]], db, bar) -> list:
    """Each recording labelled and its features extracted (`authn.enrolment.site_sample`), with
    its waveform: (sample, waveform) pairs for `authn.enrolment.on_one_waveform`."""
    from authn.enrolment import site_sample

    read = []
    with bar:
        task = bar.add_task(f"reading {len(todo)} recordings", total=len(todo))
        for f, model in todo:
            read.append(site_sample(f, model, db))
            bar.advance(task)
    return read


@models_app.command("enrol")
def enrol_cmd(
    ctx: typer.Context,
    recordings: list[Path] = typer.Argument(..., help="Recorded genuine flights from this site's radar: files or "
                                                       "directories (their .h5/.hdf5/.npz files)."),
    labels: Path | None = typer.Option(None, "--labels", help="CSV with header file,model: file relative to the "
                                                              "CSV's folder, model a registered profile slug (default: "
                                                              "each recording's Remote ID serial, looked up in the "
                                                              "registry)."),
    name: str | None = typer.Option(None, "--name", help="Site bundle name (default: site-<waveform>-<UTC time>)."),
    add: bool = typer.Option(False, "--add", help="Add these recordings to the waveform's active enrolment."),
    seed: int = typer.Option(0, "--seed", help="Seed of the simulated base set, the folds and the forest."),
    workers: int = typer.Option(2, "--workers", min=1, max=64, help="Worker processes (simulation, forest)."),
    base_samples: int = typer.Option(1500, "--base-samples", min=50, help="Simulated base returns (cached)."),
    site_bands: str = typer.Option("auto", "--site-bands",
                                   help="Re-estimate each model's rate, rotor and blade bands from the recordings, "
                                        "today's as the prior: on, off, or auto (on with one model; with several, "
                                        "measured: no gain on the held-out world)."),
    calibrate: str = typer.Option("auto", "--calibrate",
                                  help="Verify with the score calibration fitted on the cross-validated scores: "
                                       "on, off, or auto (where those scores say it pays). Always fitted and "
                                       "shown."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object at the end (progress on stderr)."),
) -> None:
    """Adapt the radar evidence to this site's radar from its recorded flights (site enrolment).

    Builds a site bundle for the recordings' waveform (a simulated base set plus the site's
    recordings, cross-validated; one model is enough: the other profiles are simulated in that
    waveform; carriers within +-2.5 % of their middle are one waveform), writes its enrolment card
    (counts, confusion matrix, pairwise errors, radar-confusable pairs and the signatures they ask
    for, threshold, carriers, source digests) and makes it the active bundle:
    `authn check` then uses it for that waveform ahead of the shipped one. Bad input (a missing
    or unknown label, another waveform, too few recordings) changes nothing.

    Example: authn models enrol flights/ --labels flights/labels.csv
    """
    from rich.console import Console

    from authn.enrolment import on_one_waveform
    from authn.sprt import Sprt
    from registry.dbapi import Database
    from signatures.train.enrol import EnrolOptions, check_counts, default_name, enrol
    from signatures.train.site_samples import EnrolError, bundle_name_ok, previous_samples
    from signatures.classify.inference import load_classifier, models_dir, set_active

    t0 = time.perf_counter()
    if name is not None and not bundle_name_ok(name):
        raise EnrolError(f"--name {name!r}: lower-case letters, digits, '.', '_' or '-' (at most 64), "
                         "not a preset name or 'shipped'")
    for flag, value in (("--calibrate", calibrate), ("--site-bands", site_bands)):
        if value not in CALIBRATE:
            raise EnrolError(f"{flag} {value!r}: one of {', '.join(CALIBRATE)}")
    db = Database(ctx.obj.db_url if ctx.obj else None)
    files = _recording_files(recordings)
    todo = _distinct(_labelled(files, labels, db))
    duplicates = len(files) - len(todo)
    console = Console(stderr=True)
    bar = _progress_bar(console)
    read = _site_samples(todo, db, bar)
    folder = _added_to(read[0][1]) if add else None
    before = load_classifier(path=folder) if folder else None  # verified before its samples are reused
    wf, samples, at = on_one_waveform(read, before.waveform if before else None)
    carriers: dict[float, int] = {}
    if folder is not None and before is not None:
        carriers = {float(k): int(v) for k, v in before.card["enrolment"].get("carriers_hz", {}).items()}
        known = {s.sha256 for s in previous_samples(folder)}
        duplicates += sum(s.sha256 in known for s in samples)  # already enrolled: the same flights again
        at = [f for s, f in zip(samples, at) if s.sha256 not in known]
        samples = previous_samples(folder) + [s for s in samples if s.sha256 not in known]
    for f in at:
        carriers[f] = carriers.get(f, 0) + 1
    profiles = _enrol_profiles(samples, db)
    check_counts(samples, profiles, duplicates)  # before any estimate or work
    name = name or default_name(wf)
    dest = models_dir() / name
    if dest.exists():
        raise EnrolError(f"{dest}: a bundle of that name exists (choose another --name)")
    counts = {m: sum(s.model == m for s in samples) for m in sorted({s.model for s in samples})}
    if duplicates:
        console.print(f"{_ignored(duplicates)} (the same bytes as another: one flight, counted once)")
    n_others = len([p for p in profiles if p not in counts])
    console.print(f"enrolling {len(samples)} recordings ({', '.join(f'{m} {n}' for m, n in counts.items())}) of "
                  f"{wf.describe()} as {name}: about {_estimate(wf, len(samples), workers, base_samples, n_others):.0f}"
                  " s (less with a cached base set)")
    with bar:
        task = bar.add_task("enrolling", total=1.0)

        def progress(phase: str, frac: float) -> None:
            bar.update(task, description=phase, completed=frac)

        card = enrol(samples, profiles, wf, dest, EnrolOptions(
            name=name, previous=folder.name if folder else None, seed=seed, workers=workers, n_sim=base_samples,
            progress=progress, sprt=Sprt(),  # track errors by the check's own test
            physics_bands=CALIBRATE[site_bands], score_calibration=CALIBRATE[calibrate], carriers=carriers))
    set_active(wf.key, name)  # only now: an interrupted enrolment leaves the previous bundle active
    _print_enrolment(card, dest, time.perf_counter() - t0, as_json, duplicates)


def _progress_bar(console):  # -> rich.progress.Progress
    """The enrolment's progress bar on stderr (none where stderr is not a terminal)."""
    import sys

    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    return Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>3.0f}%"),
                    TimeElapsedColumn(), TimeRemainingColumn(), console=console, transient=True,
                    disable=not sys.stderr.isatty())


def _added_to(wf) -> Path:
    """--add: the folder of the waveform's active site bundle."""
    from signatures.train.site_samples import EnrolError
    from signatures.classify.inference import active_bundle

    folder = active_bundle(wf)
    if folder is None:
        raise EnrolError(f"--add: no active site bundle for {wf.describe()} to add to (enrol without --add)")
    return folder


def _enrol_profiles(samples: list, db) -> dict:  # slug -> UavProfile
    """The profiles an enrolment knows: the shipped ones, every registered one (the other side of
    the card's pairs too), and each enrolled model's registered profile (EnrolError if one is not)."""
    from signatures.train.site_samples import EnrolError
    from signatures.profiles import shipped_profiles

    registered = {p.slug: p for p in db.registered_profiles()}
    for slug in sorted({s.model for s in samples}):
        p = db.profile(slug)
        if p is None:
            raise EnrolError(f"unknown model {slug!r}: not a registered model profile (authn registry models)")
        registered[slug] = p
    return {**shipped_profiles(), **registered}


def _estimate(wf, n_site: int, workers: int, n_sim: int, n_others: int = 0) -> float:
    """Seconds an enrolment takes on this machine: the base set's and the other profiles'
    simulation at the pace timed on the worker pool (`signatures.train.eta`; nothing when cached), and
    the folds' and the bundle's forests, one of them timed on a small sample."""
    from signatures.train.dataset import DatasetSpec
    from signatures.train.enrol import CV_FOLDS
    from signatures.train.impostors import N_OTHERS
    from signatures.train.eta import fit_seconds, pace, seconds
    from signatures.features import FEATURE_NAMES
    from signatures.profiles import shipped_profiles

    p = pace(DatasetSpec(preset=wf, profiles=tuple(shipped_profiles().values()), split="train", n=n_sim, seed=0),
             workers)
    per_fit = fit_seconds(n_sim + n_site, len(FEATURE_NAMES))
    return seconds(n_sim + n_others * N_OTHERS, p, CV_FOLDS + 1, per_fit)


def _ignored(duplicates: int) -> str:
    return f"{duplicates} duplicate recording{'s' if duplicates != 1 else ''} ignored"


def _print_enrolment(card: dict, folder: Path, seconds: float, as_json: bool, duplicates: int = 0) -> None:
    from rich import box
    from rich.console import Console
    from rich.table import Table

    e = card["enrolment"]
    if as_json:
        typer.echo(json.dumps({"name": e["name"], "folder": str(folder), "seconds": round(seconds, 2),
                               "counts": e["counts"], "confusion": e["confusion"], "pairwise": e["pairwise"],
                               "confusable_pairs": e["confusable_pairs"],
                               "confusable_pairs_tracks": e.get("confusable_pairs_tracks"), "tracks": e.get("tracks"),
                               "threshold": e["threshold"], "calibration": e.get("calibration"),
                               "signatures": e.get("signatures"), "carriers_hz": e.get("carriers_hz"),
                               "others": (e.get("others") or {}).get("simulated"),
                               "sources": len(e["sources"]), "duplicates_ignored": duplicates}, indent=2))
        return
    console = Console()
    console.print(f"site bundle [bold]{e['name']}[/] written to {folder} in {seconds:.0f} s; active for "
                  f"{card['preset']} recordings")
    t = Table(title="cross-validated confusion (rows: enrolled model, columns: what the system said)",
              box=box.SIMPLE_HEAD, title_justify="left")
    t.add_column("model", no_wrap=True)
    for c in e["confusion"]["cols"]:
        t.add_column(c, justify="right", no_wrap=True)
    for r, row in zip(e["confusion"]["rows"], e["confusion"]["matrix"]):
        t.add_row(r, *(str(v) for v in row))
    console.print(t)
    for p in e["pairwise"]:
        sd = p["single_dwell"]
        fa = "n/a" if sd["false_accept_rate"] is None else f"{sd['false_accept_rate']:.1%}"
        mark = ""
        if p["models"] in e["confusable_pairs"]:
            why = (f" (fewer than {e['min_separable_claims']} claims cannot show it separable)"
                   if sd["claims"] < e.get("min_separable_claims", 0) else "")
            mark = f"  radar-confusable{why}: unsigned claims rejected"
        sim = " (simulated at this radar)" if p.get("simulated") else ""
        console.print(f"  {p['models'][0]} / {p['models'][1]}{sim}: type spoofs accepted {fa} "
                      f"({sd['false_accepts']} of {sd['claims']} cross-validated claims){mark}")
        tr = p.get("tracks")
        if tr and tr["false_accept_rate"] is not None:
            mark = ("  radar-confusable over tracks" if p["models"] in (e.get("confusable_pairs_tracks") or [])
                    else "  separable over tracks")
            console.print(f"    over tracks of {tr['dwells']} dwells: type spoofs accepted "
                          f"{tr['false_accept_rate']:.1%} of {tr['claims']} drawn tracks{mark}")
    th = e["threshold"]
    console.print(f"  genuine accepted (cross-validated) at the applied threshold {th['applied']:g} nats: "
                  f"{th['genuine_accept_at_applied']:.1%}; threshold at {th['false_accept_target']:.0%} false accepts: "
                  f"{th['at_false_accept_target']}")
    cal = e.get("calibration")
    if cal:
        ev = cal["evidence_per_genuine_dwell"]
        console.print(f"  evidence per genuine dwell (cross-validated, calibrated): {ev['calibrated']} nats "
                      f"(uncalibrated {ev['uncalibrated']}); score calibration "
                      f"{'applied' if cal['applied'] else 'not applied'} ({_calibration_why(cal)})")
    _print_band_and_signatures(console, e)
    console.print(f"  card: {folder / 'card.json'} ({len(e['sources'])} source digests)")


def _print_band_and_signatures(console, e: dict) -> None:
    """The carriers the recordings were made at, and which claims need a DRIP signature."""
    carriers = e.get("carriers_hz") or {}
    if carriers:
        console.print("  carriers: " + ", ".join(f"{float(f) / 1e9:g} GHz ({n})" for f, n in carriers.items()))
    for model, need in (e.get("signatures") or {}).items():
        single, tracks = need["single_dwell"], need["tracks"]
        if not single and not tracks:
            console.print(f"  {model}: radar separates it from every other profile; no signature needed")
            continue
        console.print(f"  {model}: unsigned claims need a DRIP signature where one of these is registered: "
                      f"{', '.join(single) or 'none'} (single dwells), "
                      f"{'not measured' if tracks is None else ', '.join(tracks) or 'none'} (tracks)")


def _calibration_why(cal: dict) -> str:
    """Why the score calibration is or is not applied: asked, or what the site's own
    cross-validated claims showed (genuine accepted, worst pair's false accepts, each scoring)."""
    choice = cal.get("choice") or {}
    if choice.get("by") != "auto":
        return "as asked" if choice else "--calibrate on applies it"
    u, c = choice["uncalibrated"], choice["calibrated"]
    return (f"cross-validated {u['level'].replace('_', ' ')}: genuine accepted {u['genuine_accept']} uncalibrated, "
            f"{c['genuine_accept']} calibrated; worst pair's false accepts {u['worst_pair_false_accept']} / "
            f"{c['worst_pair_false_accept']}")


@models_app.command("use")
def use_cmd(
    name: str = typer.Argument(..., help="A site bundle's name (`authn models list`), or 'shipped'."),
) -> None:
    """Switch the active bundle: a site bundle for its waveform, or 'shipped' for every waveform.

    Example: authn models use shipped
    """
    from signatures.train.site_samples import EnrolError
    from signatures.classify.inference import card_waveform, load_classifier, models_dir, set_active

    if name == "shipped":
        set_active("*", None)
        typer.echo("the shipped (or `models train`) bundles are active for every waveform")
        return
    folder = models_dir() / name
    if "/" in name or name.startswith(".") or not (folder / "card.json").is_file():
        raise EnrolError(f"no site bundle named {name!r} in {models_dir()} (`authn models list`)")
    clf = load_classifier(path=folder)  # verified before it goes live
    if not clf.site:
        raise EnrolError(f"{name}: not a site bundle (made by `authn models enrol`); a trained bundle serves its "
                         "waveform whenever no site bundle is active")
    wf = card_waveform(clf.card)
    set_active(wf.key, name)
    typer.echo(f"{name} is active for {wf.describe()}")
