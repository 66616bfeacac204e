"""The tables `authn bench` prints, sized for an 80-column terminal.

Headers are short and wrap at spaces, figures that belong together share a cell (F1 at three
SNRs), and long labels wrap rather than truncate; `--json` keeps every value in full.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from rich.table import Table

if TYPE_CHECKING:
    from lab.bench.decisions import Row
    from lab.bench.pareto import Point
    from lab.bench.worlds import Trial

WORLD_HEADERS = {"training": "training sim", "heldout": "held-out sim"}


def _table(title: str, columns: Iterable[str], left: int = 1) -> Table:
    """A table whose first `left` columns are labels (left-aligned) and the rest figures."""
    t = Table(title=title, padding=(0, 1))
    for i, col in enumerate(columns):
        t.add_column(col, justify="left" if i < left else "right")
    return t


def decision_table(rows: list["Row"], n: int, expected: dict[str, str]) -> Table:
    t = _table(f"end-to-end decisions ({n} scenes per category, SNR 10-30 dB)",
               ("preset", "category", "want", "right", "inconcl.", "no radar", "ms"), left=3)
    for r in rows:
        t.add_row(r.preset, r.category, expected[r.category], f"{r.rate:.1%}", f"{r.inconclusive / r.n:.1%}",
                  f"{r.radar_skipped / r.n:.0%}", f"{r.median_ms:.1f}")
    return t


def stage_table(preset: str, st: dict[str, Any], fl: dict[str, float]) -> Table:
    t = _table(f"{preset}: where the time goes (median ms over {st['checks']} mixed claims, batch mode)",
               ("stage", "ms"))
    for k, v in st["stage_median_ms"].items():
        t.add_row(k, f"{v:.3f}")
    t.add_row("FFT floor (numpy, just the FFTs)", f"{fl['fft_ms']:.3f}")
    return t


def pareto_table(preset: str, pts: list["Point"], floor_ms: float, snrs: tuple[float, ...]) -> Table:
    t = _table(f"{preset}: run time against error (ms per return, x the FFT floor; same held-out returns; "
               "* = Pareto front)",
               ("configuration", "ms", "x floor", f"F1 at {'/'.join(f'{s:g}' for s in snrs)} dB", "FAR", "front"))
    for pt in pts:
        t.add_row(pt.name, f"{pt.ms_per_return:.2f}", f"{pt.ms_per_return / floor_ms:.1f}",
                  " ".join(f"{pt.f1_by_snr[s]:.3f}" for s in snrs), f"{pt.far:.3f}", "*" if pt.pareto else "")
    return t


def imports_table(imports: dict[str, float]) -> Table:
    t = _table("cold-start imports (fresh interpreter each, ms)", ("import", "ms"))
    for k, v in imports.items():
        t.add_row(k, f"{v:.0f}")
    return t


def worlds_table(trials: list["Trial"]) -> Table:
    """Share of right decisions per preset, SNR and claim, one column per world."""
    from lab.bench.worlds import WORLD_EXPECTED, correct_rates

    rates = correct_rates(trials)
    worlds = list(dict.fromkeys(t.world for t in trials))
    n = max((sum(1 for t in trials if (t.preset, t.snr_db, t.category, t.world) == k) for k in rates), default=0)
    table = _table(f"identity claims in two worlds: right decisions ({n} per cell)",
               ("preset", "SNR dB", "claim", "right is", *(WORLD_HEADERS[w] for w in worlds)), left=4)
    for key in dict.fromkeys((t.preset, t.snr_db, t.category) for t in trials):
        preset, snr, cat = key
        table.add_row(preset, f"{snr:g}", cat.replace("_", " "), WORLD_EXPECTED[cat],
                  *(f"{rates[(*key, w)]:.1%}" if (*key, w) in rates else "-" for w in worlds))
    return table


def evidence_table(trials: list["Trial"]) -> Table:
    """Per preset, SNR and claim, one column per world: the share of returns whose rotors were
    seen (the physics term ran) and the share of right decisions among them."""
    from lab.bench.worlds import evidence_rates

    rates = evidence_rates(trials)
    worlds = list(dict.fromkeys(t.world for t in trials))
    table = _table("rotors seen / right decisions where seen",
                   ("preset", "SNR dB", "claim", *(WORLD_HEADERS[w] for w in worlds)), left=3)

    def cell(key: tuple) -> str:
        if key not in rates:
            return "-"
        seen, right = rates[key]
        return f"{seen:.0%} / " + ("-" if right is None else f"{right:.0%}")

    for key in dict.fromkeys((t.preset, t.snr_db, t.category) for t in trials):
        table.add_row(key[0], f"{key[1]:g}", key[2].replace("_", " "), *(cell((*key, w)) for w in worlds))
    return table


def eer_table(trials: list["Trial"]) -> Table:
    """Equal error rate of the verification score, genuine against each impostor kind."""
    from lab.bench.worlds import equal_error_rates

    eers = equal_error_rates(trials)
    worlds = list(dict.fromkeys(t.world for t in trials))
    table = _table("verification score: equal error rate (genuine claims vs impostors)",
               ("preset", "SNR dB", "impostor", *(WORLD_HEADERS[w] for w in worlds)), left=3)
    for key in dict.fromkeys(k[:3] for k in eers):
        table.add_row(key[0], f"{key[1]:g}", key[2].replace("_", " "),
                  *(f"{eers[(*key, w)]:.1%}" if (*key, w) in eers else "-" for w in worlds))
    return table


def batch_table(report: dict[str, dict[str, Any]]) -> Table:
    """Per preset: ms per return and x the FFT floor at each batch size, then accuracy and the
    registry-only ratio (`authn bench --batch`)."""
    t = _table("batch mode: features + classifier per return (ms, x the FFT floor)",
               ("preset", "batch", "ms", "x floor"), left=2)
    for p, r in report.items():
        c = r["curve"]
        for k, ms in c["ms_per_return"].items():
            t.add_row(p, "one at a time" if k == "single" else k, f"{ms:.3f}", f"{c['x_floor'][k]:.1f}")
        t.add_row(p, "FFT floor", f"{c['fft_floor_ms']:.3f}", "1.0")
        acc, reg = r["accuracy"], r["registry_only"]
        f1 = acc["macro_f1"]
        t.add_row(p, "F1 0/10/20 dB", "single " + " ".join(f"{v:.3f}" for v in f1["single"].values()),
                  "batched " + " ".join(f"{v:.3f}" for v in f1["batched"].values()))
        t.add_row(p, "registry-only", f"{reg['registry_only_ms']:.3f}",
                  f"{reg['x_floor']:.2f} of I/O floor {reg['io_floor_ms']:.3f} ms")
    return t
