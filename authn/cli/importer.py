"""`authn import`: real radar captures as recorded returns (docs/import.md, docs/format.md)."""

from __future__ import annotations

from pathlib import Path

import typer

import_app = typer.Typer(help="Convert real radar captures to recorded-return files.", no_args_is_help=True)

_START = typer.Option(..., "--start-time", help="ISO 8601 time of the capture's first pulse (UTC offset or Z).")
_LAT = typer.Option(..., "--site-lat", help="Radar site latitude, degrees (WGS-84).")
_LON = typer.Option(..., "--site-lon", help="Radar site longitude, degrees (WGS-84).")
_ALT = typer.Option(..., "--site-alt", help="Radar site altitude, m above the WGS-84 ellipsoid.")
_OUT = typer.Option(..., "--out", help="Output .h5/.npz for one dwell; a directory when several result.")
_RID = typer.Option(None, "--rid-capture", help="pcap/pcapng Remote ID capture: the messages heard in each dwell's "
                                                 "window are written into it (docs/remoteid.md).")
_RID_SERIAL = typer.Option(None, "--rid-serial", help="With --rid-capture: the drone (UAS ID) whose messages to "
                                                      "write when the capture heard several.")
_RID_SKEW = typer.Option(2.0, "--rid-skew", min=0.0, max=3600.0, help="Capture clock-skew tolerance, s.")


def _attach(rid_capture: Path | None, rid_serial: str | None, rid_skew: float):
    """What writes a capture's messages into each dwell (None without --rid-capture). The capture
    is read once, before any dwell is written: a bad capture writes nothing."""
    if rid_capture is None:
        return None
    from authn.check import RidCapture
    from remoteid.capture import read_capture

    messages = read_capture(rid_capture)  # every dwell's window: read (and checked) once, whole
    capture = RidCapture(str(rid_capture), lambda window: [m for m in messages if m.captured_at is not None
                                                           and window[0] <= m.captured_at <= window[1]], rid_skew)
    return lambda rec: capture.attach(rec, rid_serial)


_JSON = typer.Option(False, "--json", help="Print what was written as JSON: {\"files\", \"domain\", \"shape\"}.")


def _write(dwells, n_dwells: int, capture, out: Path, domain: str, attach=None, as_json: bool = False) -> None:
    """Write the dwells (a progress bar on stderr when there are several) and say what was written."""
    import json

    from rich.console import Console
    from rich.progress import Progress

    from signatures.importers.dwell import write_dwells

    shapes: list[tuple[int, ...]] = []

    def seen(found):
        for dwell in found:
            shapes.append(dwell.iq.shape)
            yield dwell

    import sys

    bar = Progress(transient=True, console=Console(stderr=True), disable=n_dwells < 2 or not sys.stderr.isatty())
    with bar as progress:
        task = progress.add_task(f"writing {n_dwells} dwells", total=n_dwells)
        paths = write_dwells(seen(dwells), n_dwells, capture, out, lambda: progress.advance(task), attach)
    if as_json:
        typer.echo(json.dumps({"files": [str(p) for p in paths], "domain": domain, "shape": list(shapes[0][:2])}))
        return
    where = paths[0] if len(paths) == 1 and paths[0] == out else f"{out}/"
    typer.echo(f"wrote {len(paths)} '{domain}' dwell{'s' if len(paths) != 1 else ''} of "
               f"{shapes[0][0]}x{shapes[0][1]} to {where}")


@import_app.command("dca1000")
def dca1000(
    raw: list[Path] = typer.Argument(..., help="DCA1000 raw capture (adc_data_Raw_0.bin; split captures in order)."),
    config: Path = typer.Option(..., "--config", help="mmWave SDK CLI profile (.cfg) or its JSON form (.json)."),
    out: Path = _OUT,
    start_time: str = _START,
    site_lat: float = _LAT,
    site_lon: float = _LON,
    site_alt: float = _ALT,
    lanes: int = typer.Option(2, "--lanes", help="LVDS lanes of the capture: 2 (xWR14/16/18/68xx) or 4 (xWR12/22xx)."),
    rx: int | None = typer.Option(None, "--rx", help="RX antenna (physical index 0-3; default: the lowest enabled)."),
    tx: int | None = typer.Option(None, "--tx",
                                  help="TDM-MIMO: keep the loop's chirp on this TX (default: the first)."),
    frame: int | None = typer.Option(None, "--frame", min=0, help="Import this frame only (0-based; default: all)."),
    frames_per_dwell: int = typer.Option(1, "--frames-per-dwell", min=1,
                                         help="Frames joined into one dwell (only when frames follow without a gap)."),
    iq_swap: bool = typer.Option(False, "--iq-swap", help="The capture stores Q before I (adcbufCfg IQSwap 1)."),
    rid_capture: Path | None = _RID,
    rid_serial: str | None = _RID_SERIAL,
    rid_skew: float = _RID_SKEW,
    as_json: bool = _JSON,
) -> None:
    """TI mmWave + DCA1000EVM raw ADC data: one dwell (file) per frame.

    Example: authn import dca1000 adc_data_Raw_0.bin --config profile.cfg --start-time 2025-06-01T10:00:00Z \\
      --site-lat 59.35 --site-lon 18.07 --site-alt 30 --out frames/
    """
    from pydantic import ValidationError

    from core.parsing import first_error
    from signatures.errors import SignaturesError
    from signatures.importers.dca1000 import Selection, dwells, load_config
    from signatures.importers.dwell import Capture

    try:
        sel = Selection(lanes=lanes, rx=rx, tx=tx, frame=frame, frames_per_dwell=frames_per_dwell, iq_swap=iq_swap)
    except ValidationError as exc:
        loc, msg, _ = first_error(exc)
        raise SignaturesError(f"--{loc.replace('_', '-')}: {msg}") from None
    capture = Capture.parse(start_time, site_lat, site_lon, site_alt)
    attach = _attach(rid_capture, rid_serial, rid_skew)
    plan, found = dwells(raw, load_config(config), sel)
    _write(found, plan.n_dwells, capture, out, "if", attach, as_json)


@import_app.command("array")
def array(
    file: Path = typer.Argument(..., help="Samples: .npy, .npz or .mat (MATLAB v4/v5 or v7.3)."),
    domain: str | None = typer.Option(None, "--domain", help="What the samples are: if, range or cw "
                                                             "(docs/format.md); default: --radar-config's."),
    carrier_hz: float | None = typer.Option(None, "--carrier-hz", help="Carrier: frequency at the first sample of the "
                                                                     "sweep; the CW frequency."),
    radar_config: Path | None = typer.Option(None, "--radar-config",
                                             help="if: the waveform as a radar-configuration JSON (`authn models list "
                                                  "--json` prints one per bundle); options given override it."),
    out: Path = _OUT,
    start_time: str = _START,
    site_lat: float = _LAT,
    site_lon: float = _LON,
    site_alt: float = _ALT,
    pri_s: float | None = typer.Option(None, "--pri-s", help="Pulse (chirp) repetition interval, s."),
    bandwidth_hz: float | None = typer.Option(None, "--bandwidth-hz", help="if: sampled sweep bandwidth, Hz."),
    ramp_s: float | None = typer.Option(None, "--ramp-s", help="if: sampled ramp duration, s."),
    sample_rate_hz: float | None = typer.Option(None, "--sample-rate-hz",
                                                help="if: fast-time rate (real samples: the real rate); "
                                                     "cw: the IQ rate (instead of --pri-s)."),
    range_bin_m: float | None = typer.Option(None, "--range-bin-m", help="range: range-bin spacing, m."),
    first_range_m: float | None = typer.Option(None, "--first-range-m",
                                               help="if/range: range of the first bin (window start), m; default 0."),
    var: str | None = typer.Option(None, "--var",
                                   help="Variable of a .npz/.mat (default: its only one); I with --imag-var."),
    imag_var: str | None = typer.Option(None, "--imag-var", help="Variable holding Q when I and Q are real arrays."),
    interleaved: bool = typer.Option(False, "--interleaved", help="Real I, Q, I, Q, ... along the last stored axis."),
    axis_order: str = typer.Option("pulses,samples", "--axis-order",
                                   help="pulses,samples (rows are pulses) or samples,pulses (e.g. range bins x "
                                        "pulses)."),
    transpose: bool = typer.Option(False, "--transpose", help="Same as --axis-order samples,pulses."),
    pulses_per_dwell: int | None = typer.Option(None, "--pulses-per-dwell", min=1,
                                                help="Split into dwells of this many pulses (default: one dwell)."),
    rid_capture: Path | None = _RID,
    rid_serial: str | None = _RID_SERIAL,
    rid_skew: float = _RID_SKEW,
    as_json: bool = _JSON,
) -> None:
    """A numpy or MATLAB array of dechirped IF, range-compressed pulses or CW Doppler IQ.

    Example (range bins x pulses): authn import array scan.mat --var data --domain range --transpose \\
      --carrier-hz 77e9 --pri-s 1e-4 --range-bin-m 0.5 --first-range-m 20 --start-time 2025-06-01T10:00:00Z \\
      --site-lat 59.35 --site-lon 18.07 --site-alt 30 --out scan.h5

    Example (CW I and Q): authn import array cw.mat --var I --imag-var Q --domain cw --carrier-hz 24e9 \\
      --sample-rate-hz 20000 --pulses-per-dwell 4096 --start-time 2025-06-01T10:00:00Z --site-lat 59.35 \\
      --site-lon 18.07 --site-alt 30 --out cw/
    """
    from signatures.errors import SignaturesError
    from signatures.importers.array import ArraySource, Waveform, dwells
    from signatures.importers.dwell import Capture
    from signatures.recording import DOMAINS

    if radar_config is not None:  # an IF waveform's exact values; each option given overrides its field
        from signatures.radar import load_waveform

        wf = load_waveform(radar_config)
        if wf.domain != "if" or (domain or "if") != "if":
            raise SignaturesError(f"--radar-config {radar_config}: describes an IF waveform only; give range or CW "
                                  "parameters as options")
        cfg = wf.config
        domain, carrier_hz = "if", carrier_hz or cfg.carrier_hz
        pri_s, bandwidth_hz = pri_s or cfg.pri_s, bandwidth_hz or cfg.bandwidth_hz
        ramp_s, sample_rate_hz = ramp_s or cfg.ramp_s, sample_rate_hz or cfg.sample_rate_hz
        pulses_per_dwell = pulses_per_dwell or wf.n_chirps
    if domain is None or carrier_hz is None:
        raise SignaturesError("--domain and --carrier-hz are required (or --radar-config FILE.json)")
    if domain not in DOMAINS:
        raise SignaturesError(f"--domain: {domain!r} is not one of {', '.join(DOMAINS)}")
    orders = {"pulses,samples": False, "samples,pulses": True}
    if axis_order.replace(" ", "") not in orders:
        raise SignaturesError(f"--axis-order: {axis_order!r} is not one of {', '.join(orders)}")
    src = ArraySource(var=var, imag_var=imag_var, interleaved=interleaved,
                      transpose=transpose or orders[axis_order.replace(" ", "")])
    wave = Waveform(carrier_hz=carrier_hz, pri_s=pri_s, bandwidth_hz=bandwidth_hz, ramp_s=ramp_s,
                    sample_rate_hz=sample_rate_hz, range_bin_m=range_bin_m, first_range_m=first_range_m)
    capture = Capture.parse(start_time, site_lat, site_lon, site_alt)
    attach = _attach(rid_capture, rid_serial, rid_skew)
    found = dwells(file, src, domain, wave, pulses_per_dwell)
    _write(found, len(found), capture, out, domain, attach, as_json)
