"""`authn simulate`: write recorded returns of simulated scenes (docs/signal-model.md)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import typer

from core.parsing import first_error, parse_iso_time



def _scene_for(model: str, profiles_file: Path | None, **kw: object):  # -> Scene
    from signatures.errors import SignaturesError
    from signatures.profiles import load_profiles
    from signatures.scene import Scene

    if model in ("bird", "none"):
        return Scene(kind=model, **kw)  # type: ignore[arg-type]
    profiles = load_profiles()
    if profiles_file is not None:
        profiles.update(load_profiles(profiles_file))  # adds to (or overrides) the shipped profiles
    if model not in profiles:
        known = ", ".join([*profiles, "bird", "none"])
        raise SignaturesError(f"--model: unknown model {model!r} (known: {known})")
    return Scene(kind="uav", profile=profiles[model], **kw)  # type: ignore[arg-type]


def _signing(key_file: Path | None, sam: str, det: str | None, age_s: float, tamper: bool,
             fec: bool = False):  # -> Signing | None
    from core.errors import BadInput

    if key_file is None:
        if det is not None or age_s or tamper or fec:
            raise BadInput("--sign-det/--sign-age/--tamper-after-signing/--rid-fec need --sign-key")
        return None
    if sam not in ("wrapper", "manifest", "frame"):
        raise BadInput(f"--sam: {sam!r} is not wrapper, manifest or frame")
    from authn.scenario import Signing
    from authn.uakeys import load
    from remoteid.drip import DripError, parse_det

    key = load(key_file)
    try:
        named = key.det if det is None else parse_det(det)
    except DripError as exc:
        raise BadInput(f"--sign-det: {exc}") from None
    return Signing(key.private_raw, named, sam, signed_at_offset_s=-age_s, tamper_after_signing=tamper, fec=fec)


_OPTION_OF = {"range_m": "range", "radial_speed_mps": "speed", "snr_db": "snr",
              "elevation_deg": "elevation", "clutter_db": "clutter", "rotor_rate_hz": "rotor-rate",
              "tagged_blades": "tagged-blades", "tag_gain_db": "tag-gain", "clutter_to_signal_db": "clutter-to-signal"}


def _in_domain(pre, domain: str):  # (Preset, str) -> Preset
    """The preset's waveform as a radar of `domain` records it: range keeps the IF waveform (its
    range bins), CW keeps the carrier and the PRI with one sample per pulse."""
    from signatures.domain import cw_config
    from signatures.errors import SignaturesError
    from signatures.radar import DOMAINS, waveform_of

    if domain not in DOMAINS:
        raise SignaturesError(f"--domain: {domain!r} is not one of {', '.join(DOMAINS)}")
    if domain == "if":
        return pre
    if domain == "range":
        return waveform_of(pre.config, pre.n_chirps, pre.n_samples, "range", pre.max_range_m)
    return waveform_of(cw_config(pre.config.carrier_hz, pre.config.pri_s), pre.n_chirps, 1, "cw", pre.max_range_m)


def simulate(
    model: str = typer.Option(..., "--model", help="Profile slug (m600, m300, phantom4, ...), 'bird' or 'none'."),
    range_m: float = typer.Option(..., "--range", help="Slant range at the start of the dwell, metres."),
    speed: float = typer.Option(0.0, "--speed", help="Radial velocity, m/s (+ receding, 0 hovering)."),
    snr: float = typer.Option(20.0, "--snr", help="Target power / noise power per IF sample, dB."),
    out: Path = typer.Option(..., "--out", help="Output .h5 (or .npz) file; a directory with --count."),
    preset: str = typer.Option("paper", "--preset", help="Radar preset: paper, wide or cw-sband (3.3 GHz CW, 5 kHz)."),
    carrier: float | None = typer.Option(None, "--carrier", min=1e6, max=1e12,
                                         help="Carrier frequency, Hz, instead of the preset's (a radar that hops "
                                              "its carrier; a bundle serves +-2.5 % of its own)."),
    chirps: int | None = typer.Option(None, "--chirps", min=16, max=1_000_000,
                                      help="Chirps per dwell instead of the preset's (another waveform: "
                                           "`authn models train --like` builds its classifier)."),
    domain: str = typer.Option("if", "--domain",
                               help="What the file records: if (dechirped IF), range (range-compressed pulses) or "
                                    "cw (a CW radar at the preset's carrier and PRI; docs/format.md)."),
    seed: int = typer.Option(0, "--seed", help="Random seed (scene i of --count uses seed + i)."),
    elevation: float = typer.Option(10.0, "--elevation", help="Elevation of the target seen from the radar, degrees."),
    clutter: float | None = typer.Option(None, "--clutter",
                                         help="Ground clutter-to-noise ratio, dB (default: no clutter)."),
    range_offset: float | None = typer.Option(None, "--range-offset",
                                              help="Start of the range gate, m (default: target mid-window)."),
    count: int = typer.Option(1, "--count", min=1, max=1_000_000,
                              help="Number of returns (written to the --out folder as scene_NNNNNN.h5)."),
    profiles: Path | None = typer.Option(None, "--profiles",
                                         help="JSON file of UAV profiles added to (or overriding) the shipped ones."),
    azimuth: float = typer.Option(0.0, "--azimuth", help="Azimuth of the target from the radar, degrees from north."),
    rid_serial: str | None = typer.Option(None, "--rid-serial",
                                          help="Embed the Remote ID (Basic ID + Location) this drone broadcasts."),
    rid_lat: float | None = typer.Option(None, "--rid-lat", help="Declared latitude (spoof; default: the truth)."),
    rid_lon: float | None = typer.Option(None, "--rid-lon", help="Declared longitude (spoof; default: the truth)."),
    rid_alt: float | None = typer.Option(None, "--rid-alt", help="Declared WGS-84 altitude, m (spoof)."),
    rid_offset: float = typer.Option(0.0, "--rid-offset",
                                     help="Declare a position this many metres beyond the true one along the line of "
                                          "sight."),
    rid_ua_type: int = typer.Option(2, "--rid-ua-type", min=0, max=15,
                                    help="Declared F3411 UA type (2 = helicopter or multirotor)."),
    rid_id_type: int | None = typer.Option(None, "--rid-id-type", min=0, max=15,
                                           help="F3411 UAS ID type (default: 4, a session ID, for a DRIP session ID "
                                                "such as `authn keys generate` prints; else 1, a serial number)."),
    start_time: str | None = typer.Option(None, "--start-time",
                                          help="ISO 8601 UTC time of the first chirp (default: now)."),
    sign_key: Path | None = typer.Option(None, "--sign-key",
                                         help="Sign the Remote ID with this key (`authn keys generate`): DRIP, "
                                              "RFC 9575."),
    sam: str = typer.Option("wrapper", "--sam", help="DRIP authentication: wrapper, manifest or frame."),
    sign_det: str | None = typer.Option(None, "--sign-det",
                                        help="Name this DET in the signature instead of the key's own (a forgery)."),
    sign_age: float = typer.Option(0.0, "--sign-age", min=0.0,
                                   help="Signature made this many seconds before the dwell (a replay when > 300)."),
    tamper_after_signing: bool = typer.Option(False, "--tamper-after-signing",
                                              help="Move the first Location 50 m after signing it (a spoof)."),
    rid_fec: bool = typer.Option(False, "--rid-fec",
                                 help="End the authentication pages with an error-correction (FEC) page "
                                      "(XOR parity, as RFC 9575's examples; a receiver rebuilds one lost page)."),
    rotor_rate: float | None = typer.Option(None, "--rotor-rate",
                                            help="Mechanical rotor rate flown, rev/s (default: the profile's; "
                                                 "idle e.g. 67)."),
    tagged_blades: int = typer.Option(0, "--tagged-blades", min=0, max=128,
                                      help="Blades carrying a reflective tag (chosen by the seed)."),
    tag_gain: float = typer.Option(10.0, "--tag-gain", help="Power gain of a tagged blade, dB."),
    clutter_to_signal: float | None = typer.Option(None, "--clutter-to-signal",
                                                   help="Static clutter over the target's power, dB (instead "
                                                        "of --clutter)."),
    track: int = typer.Option(0, "--track", min=0, max=100_000,
                               help="Write N dwells of one target into the --out directory, --interval-s apart, "
                                    "its range moving with --speed: a track `authn check --track` takes."),
    interval_s: float | None = typer.Option(None, "--interval-s", min=1e-6, max=3600.0,
                                            help="--track: seconds between dwell starts (default: the dwell's "
                                                 "length, back to back)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object naming the files written."),
) -> None:
    """Simulate the radar return of one scene and write it as a recorded-return file.

    Example: authn simulate --model m300 --range 500 --speed 5 --snr 10 --out m300.h5

    Example (spoofed position): authn simulate --model m300 --range 500 --rid-serial 1581BDEM00000002 \\
      --rid-offset 300 --out spoof.h5

    Example (signed): authn simulate --model m300 --range 500 --rid-serial 1581BDEM00000099 \\
      --sign-key ua.pem --out signed.h5

    Example (S-band CW, 10 s, hovering, tagged): authn simulate --model phantom4 --range 300 --preset cw-sband \\
      --chirps 50000 --rotor-rate 160 --tagged-blades 2 --clutter-to-signal 30 --out cw.h5

    Example (a track of 8 dwells): authn simulate --model m300 --range 500 --rid-serial 1581BDEM00000042 \\
      --track 8 --out track/
    """
    from pydantic import ValidationError  # the Scene is a pydantic model (not on a check's path)

    from core.checked import Invalid
    from signatures.errors import SignaturesError
    from signatures.domain import as_recorded
    from signatures.radar import get_preset, waveform_of
    from signatures.recording import write_recording
    from authn.scenario import Broadcast, simulate_flight

    from core.uasid import SerialError, normalise

    if track and count > 1:
        raise SignaturesError("--track and --count: one or the other (a track is one target's dwells)")
    if track and out.suffix:
        raise SignaturesError(f"--out: with --track, give a directory (dwell_000000.h5, ...), not {out}")
    _check_out(out, count)
    if rid_serial is not None:  # what `check --serial` accepts
        try:
            normalise(rid_serial)
        except SerialError as exc:
            raise SignaturesError(f"--rid-serial: {exc}") from None
    pre = get_preset(preset)
    if chirps is not None or carrier is not None:
        cfg = pre.config if carrier is None else pre.config.replace(carrier_hz=float(carrier))
        pre = waveform_of(cfg, chirps or pre.n_chirps, pre.n_samples, pre.domain, max_range_m=pre.max_range_m)
    if pre.domain != "if" and domain not in ("if", pre.domain):
        raise SignaturesError(f"--domain: preset {preset!r} records {pre.domain}, not {domain}")
    pre = pre if pre.domain != "if" else _in_domain(pre, domain)
    if not 0 < range_m <= pre.max_range_m:
        raise SignaturesError(f"--range: {range_m:g} m is outside (0, {pre.max_range_m:g}] m of preset {preset!r}")
    try:
        scene = _scene_for(model, profiles, range_m=range_m, radial_speed_mps=speed, snr_db=snr,
                           elevation_deg=elevation, clutter_db=clutter, rotor_rate_hz=rotor_rate,
                           tagged_blades=tagged_blades, tag_gain_db=tag_gain, clutter_to_signal_db=clutter_to_signal)
    except (ValidationError, Invalid) as exc:
        loc, msg, _ = first_error(exc)
        field = loc.split(".")[0] or "model"
        raise SignaturesError(f"--{_OPTION_OF.get(field, field)}: {msg}") from None
    from datetime import datetime, timezone

    start = datetime.now(timezone.utc) if start_time is None else \
        parse_iso_time(start_time, "--start-time", error=SignaturesError)
    broadcast = None
    signing = _signing(sign_key, sam, sign_det, sign_age, tamper_after_signing, rid_fec)
    if rid_serial is not None:
        if rid_id_type is None:
            rid_id_type = 4 if re.fullmatch(r"01[0-9A-Fa-f]{32}", rid_serial) else 1
            rid_serial = rid_serial.upper() if rid_id_type == 4 else rid_serial
        broadcast = Broadcast(serial=rid_serial, ua_type=rid_ua_type, id_type=rid_id_type, lat_deg=rid_lat,
                              lon_deg=rid_lon, alt_m=rid_alt, offset_along_los_m=rid_offset, signing=signing)
    elif any(v is not None for v in (rid_lat, rid_lon, rid_alt)) or rid_offset or signing is not None:
        raise SignaturesError("--rid-lat/--rid-lon/--rid-alt/--rid-offset/--sign-key need --rid-serial")

    from datetime import timedelta

    step_s = (interval_s if interval_s is not None else pre.dwell_s) if track else 0.0

    def run_simulation(i: int):
        moved = scene
        if track:  # dwell i: step_s later, its range moved by the radial speed
            r = range_m + speed * i * step_s
            if not 0 < r <= pre.max_range_m:
                raise SignaturesError(f"--track: dwell {i} would be at {r:g} m, outside (0, {pre.max_range_m:g}] m")
            moved = scene.model_copy(update={"range_m": r})
        try:
            rec, truth = simulate_flight(moved, pre, seed + i, broadcast, azimuth, range_offset,
                                         start + timedelta(seconds=i * step_s))
            return as_recorded(rec, pre.domain), truth
        except (ValidationError, Invalid) as exc:
            loc, msg, _ = first_error(exc)
            raise SignaturesError(f"--rid-*: {loc}: {msg}") from None

    def written(path: Path, rec, truth) -> dict:
        return {"file": str(path), "range_gate_m": rec.config.range_offset_m,
                "blade_flash_rate_hz": truth.blade_flash_rate_hz}

    def report(files: list[dict], rec) -> None:
        typer.echo(json.dumps({"model": scene.label, "waveform": pre.name, "domain": pre.domain,
                               "shape": [rec.n_chirps, rec.n_samples], "files": files}, indent=2))

    if count == 1 and not track and out.suffix:
        rec, truth = run_simulation(0)
        write_recording(rec, out)
        if as_json:
            report([written(out, rec, truth)], rec)
            return
        typer.echo(f"wrote {out} ({scene.label}, {rec.n_chirps}x{rec.n_samples}, "
                   f"range gate {rec.config.range_offset_m:g} m, flash rate {truth.blade_flash_rate_hz:.1f} Hz)")
        return
    from rich.progress import Progress

    out.mkdir(parents=True, exist_ok=True)
    files = []
    n, stem = (track, "dwell") if track else (count, "scene")
    with Progress(transient=True, disable=as_json) as progress:
        task = progress.add_task(f"simulating {n} x {scene.label}", total=n)
        for i in range(n):
            rec, truth = run_simulation(i)
            path = write_recording(rec, out / f"{stem}_{i:06d}.h5")
            files.append(written(path, rec, truth))
            progress.advance(task)
    if as_json:
        report(files, rec)
        return
    typer.echo(f"wrote {n} {'dwells of one track' if track else 'returns'} to {out}/"
               + (f" ({step_s:g} s apart)" if track else ""))


def _check_out(out: Path, count: int) -> None:
    """--out: a .h5/.hdf5/.npz file for one scene, a directory (no suffix) for --count N."""
    from signatures.errors import SignaturesError
    from signatures.recording import RECORDING_SUFFIXES

    suffix = out.suffix.lower()
    if count > 1 and suffix in RECORDING_SUFFIXES:
        raise SignaturesError(f"--out: with --count {count}, give a directory, not the file name {out}")
    if count == 1 and suffix and suffix not in RECORDING_SUFFIXES and not out.is_dir():
        raise SignaturesError(f"--out {out}: a recorded return is written as .h5 (HDF5) or .npz, "
                              f"not {out.suffix}; a directory of returns: --count N")
