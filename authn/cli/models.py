"""`authn models train / evaluate`: build the classifier bundles and print the paper's metrics."""

from __future__ import annotations

import json
import time
from pathlib import Path

import typer


models_app = typer.Typer(help="Train and evaluate the radar classifiers (kNN, RF, SVM, ensemble, CNN).",
                         no_args_is_help=True)


def _profiles(files: list[Path] | None, preset_default: bool = True):  # -> tuple[UavProfile, ...]
    from signatures.profiles import load_profiles, shipped_profiles

    out = dict(shipped_profiles()) if preset_default else {}
    for f in files or []:
        out.update(load_profiles(f))
    return tuple(out.values())


@models_app.command("train")
def train(
    preset: str = typer.Option("paper", "--preset", help="Radar preset: paper or wide."),
    profiles: list[Path] | None = typer.Option(None, "--profiles",
                                               help="JSON file of extra UAV profiles to enrol (repeatable)."),
    samples: int | None = typer.Option(None, "--samples", min=50, help="Training returns (default: 8000 paper, 4000 wide)."),
    val_samples: int | None = typer.Option(None, "--val-samples", min=50, help="Validation returns (default: samples / 4)."),
    seed: int = typer.Option(0, "--seed", help="Training seed (datasets, forests, SVM, CNN)."),
    cnn: bool = typer.Option(False, "--cnn", help="Also train the RD-patch CNN (needs torch) and the cascade."),
    out: Path | None = typer.Option(None, "--out", help="Bundle folder (default: the shipped bundle of the preset)."),
    workers: int = typer.Option(2, "--workers", min=1, max=64, help="Simulation worker processes."),
) -> None:
    """Simulate, train and export a model bundle (numpy arrays, ONNX files, model card).

    Example: authn models train --preset paper --cnn
    """
    from rich.console import Console

    from signatures.inference import bundle_dir
    from signatures.radar import get_preset
    from signatures.training import TrainConfig, train_bundle

    get_preset(preset)
    n = samples or (8000 if preset == "paper" else 4000)
    known = _profiles(profiles)
    n_val = val_samples or max(n // 4, 50)
    unknown = tuple(p for p in _invented() if p.slug not in {k.slug for k in known})
    cfg = TrainConfig(preset=preset, profiles=known, n_train=n, n_val=n_val, seed=seed, cnn=cnn, workers=workers,
                      unknown_profiles=unknown, n_unknown_val=max(n_val // 4, 20))
    folder = out or bundle_dir(preset)
    t0 = time.perf_counter()
    card = train_bundle(cfg, folder, progress=True)
    console = Console()
    console.print(f"[bold]{preset}[/] bundle written to {folder} in {time.perf_counter() - t0:.0f} s")
    for name, m in card["metrics"]["validation"].items():
        console.print(f"  validation {name}: {m}")


@models_app.command("evaluate")
def evaluate(
    preset: str = typer.Option("paper", "--preset", help="Radar preset whose shipped bundle to evaluate."),
    model: Path | None = typer.Option(None, "--model", help="Bundle folder (default: the shipped one)."),
    snr: str = typer.Option("-20,-15,-10,-5,0,5,10,20,30", "--snr", help="Comma-separated SNRs (dB)."),
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
    from signatures.evaluate import evaluate as run_eval
    from signatures.evaluate import plot, write_json
    from signatures.inference import load_classifier
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
    from importlib import resources

    from signatures.profiles import parse_profiles

    text = resources.files("signatures.data").joinpath("openset_profiles.json").read_text()
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
