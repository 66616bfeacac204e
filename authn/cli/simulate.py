"""`authn simulate`: write recorded returns of simulated scenes (docs/signal-model.md)."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from core.parsing import first_error, parse_iso_time

if TYPE_CHECKING:
    from authn.scenario import Broadcast
    from signatures.radar import Preset
    from signatures.sim.scene import Scene



def _scene_for(model: str, profiles_file: Path | None, **kw: object):  # -> Scene
    from signatures.errors import SignaturesError
    from signatures.profiles import load_profiles
    from signatures.sim.scene import Scene

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
    from signatures.sim.domain import cw_config
    from signatures.errors import SignaturesError
    from signatures.radar import DOMAINS, waveform_of

    if domain not in DOMAINS:
        raise SignaturesError(f"--domain: {domain!r} is not one of {', '.join(DOMAINS)}")
    if domain == "if":
        return pre
    if domain == "range":
        return waveform_of(pre.config, pre.n_chirps, pre.n_samples, "range", pre.max_range_m)
    return waveform_of(cw_config(pre.config.carrier_hz, pre.config.pri_s), pre.n_chirps, 1, "cw", pre.max_range_m)


_MODEL = typer.Option(..., "--model", help="Profile slug (m600, m300, phantom4, ...), 'bird' or 'none'.")
_RANGE = typer.Option(..., "--range", help="Slant range at the start of the dwell, metres.")
_SPEED = typer.Option(0.0, "--speed", help="Radial velocity, m/s (+ receding, 0 hovering).")
_SNR = typer.Option(20.0, "--snr", help="Target power / noise power per IF sample, dB.")
_OUT = typer.Option(..., "--out", help="Output .h5 (or .npz) file; a directory with --count.")
_PRESET = typer.Option("paper", "--preset", help="Radar preset: paper, wide or cw-sband (3.3 GHz CW, 5 kHz).")
_CARRIER = typer.Option(None, "--carrier", min=1e6, max=1e12,
                        help="Carrier frequency, Hz, instead of the preset's (a radar that hops "
                             "its carrier; a bundle serves +-2.5 % of its own).")
_CHIRPS = typer.Option(None, "--chirps", min=16, max=1_000_000,
                       help="Chirps per dwell instead of the preset's (another waveform: "
                            "`authn models train --like` builds its classifier).")
_DOMAIN = typer.Option("if", "--domain",
                       help="What the file records: if (dechirped IF), range (range-compressed pulses) or "
                            "cw (a CW radar at the preset's carrier and PRI; docs/format.md).")
_SEED = typer.Option(0, "--seed", help="Random seed (scene i of --count uses seed + i).")
_ELEVATION = typer.Option(10.0, "--elevation", help="Elevation of the target seen from the radar, degrees.")
_CLUTTER = typer.Option(None, "--clutter", help="Ground clutter-to-noise ratio, dB (default: no clutter).")
_RANGE_OFFSET = typer.Option(None, "--range-offset", help="Start of the range gate, m (default: target mid-window).")
_COUNT = typer.Option(1, "--count", min=1, max=1_000_000,
                      help="Number of returns (written to the --out folder as scene_NNNNNN.h5).")
_PROFILES = typer.Option(None, "--profiles",
                         help="JSON file of UAV profiles added to (or overriding) the shipped ones.")
_AZIMUTH = typer.Option(0.0, "--azimuth", help="Azimuth of the target from the radar, degrees from north.")
_RID_SERIAL = typer.Option(None, "--rid-serial",
                           help="Embed the Remote ID (Basic ID + Location) this drone broadcasts.")
_RID_LAT = typer.Option(None, "--rid-lat", help="Declared latitude (spoof; default: the truth).")
_RID_LON = typer.Option(None, "--rid-lon", help="Declared longitude (spoof; default: the truth).")
_RID_ALT = typer.Option(None, "--rid-alt", help="Declared WGS-84 altitude, m (spoof).")
_RID_OFFSET = typer.Option(0.0, "--rid-offset",
                           help="Declare a position this many metres beyond the true one along the line of sight.")
_RID_UA_TYPE = typer.Option(2, "--rid-ua-type", min=0, max=15,
                            help="Declared F3411 UA type (2 = helicopter or multirotor).")
_RID_ID_TYPE = typer.Option(None, "--rid-id-type", min=0, max=15,
                            help="F3411 UAS ID type (default: 4, a session ID, for a DRIP session ID "
                                 "such as `authn keys generate` prints; else 1, a serial number).")
_START_TIME = typer.Option(None, "--start-time", help="ISO 8601 UTC time of the first chirp (default: now).")
_SIGN_KEY = typer.Option(None, "--sign-key",
                         help="Sign the Remote ID with this key (`authn keys generate`): DRIP, RFC 9575.")
_SAM = typer.Option("wrapper", "--sam", help="DRIP authentication: wrapper, manifest or frame.")
_SIGN_DET = typer.Option(None, "--sign-det",
                         help="Name this DET in the signature instead of the key's own (a forgery).")
_SIGN_AGE = typer.Option(0.0, "--sign-age", min=0.0,
                         help="Signature made this many seconds before the dwell (a replay when > 300).")
_TAMPER = typer.Option(False, "--tamper-after-signing", help="Move the first Location 50 m after signing it (a spoof).")
_RID_FEC = typer.Option(False, "--rid-fec",
                        help="End the authentication pages with an error-correction (FEC) page "
                             "(XOR parity, as RFC 9575's examples; a receiver rebuilds one lost page).")
_ROTOR_RATE = typer.Option(None, "--rotor-rate",
                           help="Mechanical rotor rate flown, rev/s (default: the profile's; idle e.g. 67).")
_TAGGED_BLADES = typer.Option(0, "--tagged-blades", min=0, max=128,
                              help="Blades carrying a reflective tag (chosen by the seed).")
_TAG_GAIN = typer.Option(10.0, "--tag-gain", help="Power gain of a tagged blade, dB.")
_CLUTTER_TO_SIGNAL = typer.Option(None, "--clutter-to-signal",
                                  help="Static clutter over the target's power, dB (instead of --clutter).")
_TRACK = typer.Option(0, "--track", min=0, max=100_000,
                      help="Write N dwells of one target into the --out directory, --interval-s apart, "
                           "its range moving with --speed: a track `authn check --track` takes.")
_INTERVAL_S = typer.Option(None, "--interval-s", min=1e-6, max=3600.0,
                           help="--track: seconds between dwell starts (default: the dwell's length, back to back).")
_JSON = typer.Option(False, "--json", help="Print one JSON object naming the files written.")


@dataclass(frozen=True)
class SimulateRequest:
    """Everything `authn simulate` was asked for, one field per option (built once from them)."""

    model: str
    range_m: float
    speed: float
    snr: float
    out: Path
    preset: str
    carrier: float | None
    chirps: int | None
    domain: str
    seed: int
    elevation: float
    clutter: float | None
    range_offset: float | None
    count: int
    profiles: Path | None
    azimuth: float
    rid_serial: str | None
    rid_lat: float | None
    rid_lon: float | None
    rid_alt: float | None
    rid_offset: float
    rid_ua_type: int
    rid_id_type: int | None
    start_time: str | None
    sign_key: Path | None
    sam: str
    sign_det: str | None
    sign_age: float
    tamper_after_signing: bool
    rid_fec: bool
    rotor_rate: float | None
    tagged_blades: int
    tag_gain: float
    clutter_to_signal: float | None
    track: int
    interval_s: float | None
    as_json: bool


def simulate(
    model: str = _MODEL, range_m: float = _RANGE, speed: float = _SPEED, snr: float = _SNR, out: Path = _OUT,
    preset: str = _PRESET, carrier: float | None = _CARRIER, chirps: int | None = _CHIRPS, domain: str = _DOMAIN,
    seed: int = _SEED, elevation: float = _ELEVATION, clutter: float | None = _CLUTTER,
    range_offset: float | None = _RANGE_OFFSET, count: int = _COUNT, profiles: Path | None = _PROFILES,
    azimuth: float = _AZIMUTH, rid_serial: str | None = _RID_SERIAL, rid_lat: float | None = _RID_LAT,
    rid_lon: float | None = _RID_LON, rid_alt: float | None = _RID_ALT, rid_offset: float = _RID_OFFSET,
    rid_ua_type: int = _RID_UA_TYPE, rid_id_type: int | None = _RID_ID_TYPE, start_time: str | None = _START_TIME,
    sign_key: Path | None = _SIGN_KEY, sam: str = _SAM, sign_det: str | None = _SIGN_DET,
    sign_age: float = _SIGN_AGE, tamper_after_signing: bool = _TAMPER, rid_fec: bool = _RID_FEC,
    rotor_rate: float | None = _ROTOR_RATE, tagged_blades: int = _TAGGED_BLADES, tag_gain: float = _TAG_GAIN,
    clutter_to_signal: float | None = _CLUTTER_TO_SIGNAL, track: int = _TRACK, interval_s: float | None = _INTERVAL_S,
    as_json: bool = _JSON,
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
    req = SimulateRequest(**locals())  # first: the locals are exactly the options
    _check_request(req)
    pre = _waveform(req)
    scene = _scene(req, pre)
    start = _start(req)
    _run(req, pre, scene, _broadcast(req), start)


def _check_request(req: SimulateRequest) -> None:
    """Refuse what no waveform makes sense of: --track with --count, a track into a file, a bad
    --out, a --rid-serial that `check --serial` would not accept."""
    from core.uasid import SerialError, normalise
    from signatures.errors import SignaturesError

    if req.track and req.count > 1:
        raise SignaturesError("--track and --count: one or the other (a track is one target's dwells)")
    if req.track and req.out.suffix:
        raise SignaturesError(f"--out: with --track, give a directory (dwell_000000.h5, ...), not {req.out}")
    _check_out(req.out, req.count)
    if req.rid_serial is not None:  # what `check --serial` accepts
        try:
            normalise(req.rid_serial)
        except SerialError as exc:
            raise SignaturesError(f"--rid-serial: {exc}") from None


def _waveform(req: SimulateRequest) -> Preset:
    """The preset with --chirps / --carrier applied, as a radar of --domain records it; refuses a
    --range beyond its reach."""
    from signatures.errors import SignaturesError
    from signatures.radar import get_preset, waveform_of

    pre = get_preset(req.preset)
    if req.chirps is not None or req.carrier is not None:
        cfg = pre.config if req.carrier is None else pre.config.replace(carrier_hz=float(req.carrier))
        pre = waveform_of(cfg, req.chirps or pre.n_chirps, pre.n_samples, pre.domain, max_range_m=pre.max_range_m)
    if pre.domain != "if" and req.domain not in ("if", pre.domain):
        raise SignaturesError(f"--domain: preset {req.preset!r} records {pre.domain}, not {req.domain}")
    pre = pre if pre.domain != "if" else _in_domain(pre, req.domain)
    if not 0 < req.range_m <= pre.max_range_m:
        raise SignaturesError(f"--range: {req.range_m:g} m is outside (0, {pre.max_range_m:g}] m "
                              f"of preset {req.preset!r}")
    return pre


def _scene(req: SimulateRequest, pre: Preset) -> Scene:
    """The scene asked for; an invalid value names its option."""
    from pydantic import ValidationError  # the Scene is a pydantic model (not on a check's path)

    from core.checked import Invalid
    from signatures.errors import SignaturesError

    try:
        return _scene_for(req.model, req.profiles, range_m=req.range_m, radial_speed_mps=req.speed, snr_db=req.snr,
                          elevation_deg=req.elevation, clutter_db=req.clutter, rotor_rate_hz=req.rotor_rate,
                          tagged_blades=req.tagged_blades, tag_gain_db=req.tag_gain,
                          clutter_to_signal_db=req.clutter_to_signal)
    except (ValidationError, Invalid) as exc:
        loc, msg, _ = first_error(exc)
        field = loc.split(".")[0] or "model"
        raise SignaturesError(f"--{_OPTION_OF.get(field, field)}: {msg}") from None


def _start(req: SimulateRequest) -> datetime:
    """The first chirp's time: --start-time, else now."""
    from signatures.errors import SignaturesError

    if req.start_time is None:
        return datetime.now(timezone.utc)
    return parse_iso_time(req.start_time, "--start-time", error=SignaturesError)


def _broadcast(req: SimulateRequest) -> Broadcast | None:
    """The Remote ID broadcast (--rid-*, signed with --sign-key), None without --rid-serial."""
    from authn.scenario import Broadcast
    from signatures.errors import SignaturesError

    signing = _signing(req.sign_key, req.sam, req.sign_det, req.sign_age, req.tamper_after_signing, req.rid_fec)
    serial, id_type = req.rid_serial, req.rid_id_type
    if serial is None:
        if any(v is not None for v in (req.rid_lat, req.rid_lon, req.rid_alt)) or req.rid_offset or signing is not None:
            raise SignaturesError("--rid-lat/--rid-lon/--rid-alt/--rid-offset/--sign-key need --rid-serial")
        return None
    if id_type is None:
        id_type = 4 if re.fullmatch(r"01[0-9A-Fa-f]{32}", serial) else 1
        serial = serial.upper() if id_type == 4 else serial
    return Broadcast(serial=serial, ua_type=req.rid_ua_type, id_type=id_type, lat_deg=req.rid_lat,
                     lon_deg=req.rid_lon, alt_m=req.rid_alt, offset_along_los_m=req.rid_offset, signing=signing)


@dataclass(frozen=True)
class _Flight:
    """One scene's dwells to simulate: dwell i starts `step_s` after dwell i - 1, its range moved
    by the radial speed (a track), else every dwell is the scene itself (seed + i)."""

    req: SimulateRequest
    pre: Preset
    scene: Scene
    broadcast: Broadcast | None
    start: datetime
    step_s: float

    def dwell(self, i: int):  # -> (Recording, Truth)
        """Dwell i, as the preset's domain records it, and its truth."""
        from pydantic import ValidationError

        from authn.scenario import simulate_flight
        from core.checked import Invalid
        from signatures.sim.domain import as_recorded
        from signatures.errors import SignaturesError

        req, pre, moved = self.req, self.pre, self.scene
        if req.track:  # dwell i: step_s later, its range moved by the radial speed
            r = req.range_m + req.speed * i * self.step_s
            if not 0 < r <= pre.max_range_m:
                raise SignaturesError(f"--track: dwell {i} would be at {r:g} m, outside (0, {pre.max_range_m:g}] m")
            moved = moved.model_copy(update={"range_m": r})
        try:
            rec, truth = simulate_flight(moved, pre, req.seed + i, self.broadcast, req.azimuth, req.range_offset,
                                         self.start + timedelta(seconds=i * self.step_s))
            return as_recorded(rec, pre.domain), truth
        except (ValidationError, Invalid) as exc:
            loc, msg, _ = first_error(exc)
            raise SignaturesError(f"--rid-*: {loc}: {msg}") from None


def _run(req: SimulateRequest, pre: Preset, scene: Scene, broadcast: Broadcast | None, start: datetime) -> None:
    """Simulate and write: one file, or --count scenes / --track dwells into the --out folder."""
    from signatures.recording import write_recording

    step_s = (req.interval_s if req.interval_s is not None else pre.dwell_s) if req.track else 0.0
    flight = _Flight(req, pre, scene, broadcast, start, step_s)
    if req.count == 1 and not req.track and req.out.suffix:
        rec, truth = flight.dwell(0)
        write_recording(rec, req.out)
        if req.as_json:
            _report(req, flight, [_written(req.out, rec, truth)], rec)
            return
        typer.echo(f"wrote {req.out} ({scene.label}, {rec.n_chirps}x{rec.n_samples}, "
                   f"range gate {rec.config.range_offset_m:g} m, flash rate {truth.blade_flash_rate_hz:.1f} Hz)")
        return
    from rich.progress import Progress

    req.out.mkdir(parents=True, exist_ok=True)
    files = []
    n, stem = (req.track, "dwell") if req.track else (req.count, "scene")
    with Progress(transient=True, disable=req.as_json) as progress:
        task = progress.add_task(f"simulating {n} x {scene.label}", total=n)
        for i in range(n):
            rec, truth = flight.dwell(i)
            path = write_recording(rec, req.out / f"{stem}_{i:06d}.h5")
            files.append(_written(path, rec, truth))
            progress.advance(task)
    if req.as_json:
        _report(req, flight, files, rec)
        return
    typer.echo(f"wrote {n} {'dwells of one track' if req.track else 'returns'} to {req.out}/"
               + (f" ({step_s:g} s apart)" if req.track else ""))


def _written(path: Path, rec, truth) -> dict:
    """One file's entry in the --json output."""
    return {"file": str(path), "range_gate_m": rec.config.range_offset_m,
            "blade_flash_rate_hz": truth.blade_flash_rate_hz}


def _report(req: SimulateRequest, flight: _Flight, files: list[dict], rec) -> None:
    """The --json output: the scene, the waveform and the files written."""
    typer.echo(json.dumps({"model": flight.scene.label, "waveform": flight.pre.name, "domain": flight.pre.domain,
                           "shape": [rec.n_chirps, rec.n_samples], "files": files}, indent=2))


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
