"""What every importer shares: the site and time of a capture, its dwells as Recordings,
where they are written, and real IF made complex (docs/import.md).

An importer turns a foreign capture into `Dwell`s (samples, waveform, domain, offset of
the first pulse from the capture's start); `write_dwells` places them at the site and
time the user gives and writes one recorded-return file per dwell (docs/format.md).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

from core.checked import Invalid
from core.parsing import parse_iso_time
from signatures.errors import SignaturesError
from signatures.radar import RadarConfig
from signatures.recording import (EARLIEST_START, MAX_FUTURE_SKEW, MAX_IQ_CELLS, RECORDING_SUFFIXES, RadarSite,
                                  Recording, write_recording)

__all__ = ["Capture", "Dwell", "analytic_half_rate", "radar_config", "write_dwells"]

@dataclass(frozen=True)
class Capture:
    """Where and when a capture was made: the site and the time of its first pulse."""

    site: RadarSite
    start_time: datetime

    @classmethod
    def parse(cls, start_time: str, lat_deg: float, lon_deg: float, alt_m: float) -> "Capture":
        """From the CLI's text and numbers; one-line errors naming the option."""
        when = parse_iso_time(start_time, "--start-time", error=SignaturesError).astimezone(timezone.utc)
        try:
            site = RadarSite(lat_deg=lat_deg, lon_deg=lon_deg, alt_m=alt_m)
        except Invalid as exc:
            raise SignaturesError(f"--site-{exc.loc.split('_')[0]}: {exc.msg}") from None
        return cls(site, when)


@dataclass(frozen=True)
class Dwell:
    """One dwell of an import: `/iq`, its waveform and domain, and when it starts."""

    iq: np.ndarray
    config: RadarConfig
    domain: str
    offset_s: float  # first pulse, seconds after the capture's start
    label: str  # names the file: frame_000003, dwell_000012


def radar_config(what: str, **values: float) -> RadarConfig:
    """A RadarConfig, or a one-line error naming the attribute and what it came from."""
    try:
        return RadarConfig(**values)
    except Invalid as exc:
        field = exc.loc.split(".")[0] or "pri_s"
        shown = f" (got {exc.value:g})" if isinstance(exc.value, float) else ""
        raise SignaturesError(f"{what}: radar attribute '{field}': {exc.msg}{shown}") from None


def analytic_half_rate(real: np.ndarray) -> np.ndarray:
    """Real IF samples (last axis, n even, rate fs) as complex samples at fs/2 (n/2 of them).

    The analytic signal (FFT, negative frequencies zeroed, positive ones doubled, DC and
    Nyquist kept once) holds the beat band [0, fs/2) only, so every second sample keeps all
    of it: bin k of the result's FFT is bin k of the real FFT, and the sampled bandwidth and
    ramp are unchanged. complex64 unless the input is float64.
    """
    n = real.shape[-1]
    if n % 2:
        raise SignaturesError(f"real ADC samples: need an even number per chirp to make them complex, got {n}")
    spec = np.fft.fft(real, axis=-1)
    h = np.zeros(n)
    h[0] = h[n // 2] = 1.0
    h[1:n // 2] = 2.0
    z = np.fft.ifft(spec * h, axis=-1)[..., ::2]
    return z.astype(np.complex128 if real.dtype == np.float64 else np.complex64)


def _start(capture: Capture, dwell: Dwell) -> datetime:
    when = capture.start_time + timedelta(seconds=dwell.offset_s)
    latest = datetime.now(timezone.utc) + MAX_FUTURE_SKEW
    if not EARLIEST_START <= when <= latest:
        raise SignaturesError(f"--start-time: dwell {dwell.label} would start at {when.isoformat()}, outside "
                              f"{EARLIEST_START:%Y-%m-%d} .. now + {MAX_FUTURE_SKEW.seconds // 60} min")
    return when


def write_dwells(dwells: Iterable[Dwell], n_dwells: int, capture: Capture, out: Path,
                 advance: Callable[[], None] = lambda: None,
                 attach: Callable[[Recording], Recording] | None = None) -> list[Path]:
    """Write each dwell as a recorded return at the capture's site and time (no Remote ID;
    `attach` may add it: `authn import --rid-capture`); `--out` is the file when there is one
    dwell and it has a recording suffix (.h5, .hdf5, .npz), else a directory of `<label>.h5`."""
    as_file = out.suffix.lower() in RECORDING_SUFFIXES
    if as_file and n_dwells != 1:
        raise SignaturesError(f"--out: {n_dwells} dwells result; give a directory, not the file name {out}")
    paths: list[Path] = []
    for dwell in dwells:
        if dwell.iq.size > MAX_IQ_CELLS:
            raise SignaturesError(f"dwell {dwell.label}: {dwell.iq.shape[0]}x{dwell.iq.shape[1]} cells exceed the "
                                  f"reader's limit of {MAX_IQ_CELLS}; import fewer pulses per dwell")
        rec = Recording(config=dwell.config, site=capture.site, start_time=_start(capture, dwell), iq=dwell.iq,
                        domain=dwell.domain)
        if attach is not None:
            rec = attach(rec)
        paths.append(write_recording(rec, out if as_file else out / f"{dwell.label}.h5"))
        advance()
    return paths
