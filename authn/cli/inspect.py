"""`authn inspect`: validate a recorded return and report what its waveform can measure."""

from __future__ import annotations

import json
from pathlib import Path

import typer



def inspect_file(
    file: Path = typer.Argument(..., help="Recorded return (.h5 or .npz)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Validate a recorded-return file and print its radar configuration report.

    The report gives the range window and resolution, the unambiguous velocity,
    the Doppler bin, and for each shipped UAV profile whether its blade-tip
    micro-Doppler aliases at this PRF.

    Example: authn inspect m300.h5 --json
    """
    from signatures.profiles import shipped_profiles
    from signatures.radar import describe
    from signatures.recording import read_recording

    rec = read_recording(file)
    cw = getattr(rec, "domain", "if") == "cw"  # no sweep: no range axis to report
    report = {
        "file": str(file),
        "shape": [rec.n_chirps, rec.n_samples],
        "dtype": str(rec.iq.dtype),
        "start_time": rec.start_time.isoformat(),
        "site": rec.site.to_dict(),
        "config": rec.config.to_dict(),
        "derived": describe(rec.config, rec.n_chirps, rec.n_samples, shipped_profiles()),
        "domain": getattr(rec, "domain", "if"),
        "remote_id_messages": 0 if rec.remote_id is None else int(rec.remote_id.shape[0]),
        "simulation": json.loads(rec.simulation) if rec.simulation else None,
    }
    if cw:  # unmeasurable without a sweep: null, never a number
        report["derived"].update(range_resolution_m=None, range_bin_m=None, range_window_m=None)
    if as_json:
        typer.echo(json.dumps(report, indent=2))
        return
    from rich.table import Table

    from authn.cli.output import print_table

    d = report["derived"]
    table = Table(title=f"{file} ({rec.n_chirps} chirps x {rec.n_samples} samples, {rec.iq.dtype})")
    table.add_column("quantity", no_wrap=True)
    table.add_column("value", justify="right", no_wrap=True)
    na = "n/a (CW)"
    lo, hi = d["range_window_m"] or (0.0, 0.0)
    rows = [
        ("domain", report["domain"]),
        ("carrier", f"{rec.config.carrier_hz / 1e9:.3f} GHz"),
        ("bandwidth", na if cw else f"{rec.config.bandwidth_hz / 1e6:.1f} MHz"),
        ("ramp / PRI", f"{na} / {rec.config.pri_s * 1e6:.2f} us" if cw
         else f"{rec.config.ramp_s * 1e6:.2f} / {rec.config.pri_s * 1e6:.2f} us"),
        ("range window", na if cw else f"{lo:.1f} .. {hi:.1f} m"),
        ("range resolution", na if cw else f"{d['range_resolution_m']:.3f} m"),
        ("unambiguous velocity", f"+-{d['unambiguous_velocity_mps']:.2f} m/s"),
        ("Doppler bin", f"{d['doppler_bin_mps']:.4f} m/s"),
        ("dwell", f"{d['dwell_s'] * 1e3:.2f} ms"),
        ("Remote ID messages", str(report["remote_id_messages"])),
    ]
    for slug, tip in d["blade_tips"].items():
        rows.append((f"{slug} tip Doppler", f"{tip['tip_doppler_hz'] / 1e3:.1f} kHz"
                     + (" (aliases)" if tip["aliases_when_hovering"] else "")))
    for k, v in rows:
        table.add_row(k, v)
    print_table(table)
