"""TI mmWave + DCA1000EVM raw ADC captures (`adc_data_Raw_0.bin`) as recorded returns.

The layout is TI's (SWRA581B, "mmWave Radar Device ADC Raw Data Capture", and its
readDCA1000.m): little-endian int16, frame after frame, chirp after chirp (loops x the
frame's chirps), no headers. Within a chirp, 2 LVDS lanes (xWR14xx/16xx/18xx/68xx): the
enabled RX one after the other, each its samples; complex samples come in groups of four
words I(k) I(k+1) Q(k) Q(k+1). 4 lanes (xWR12xx/22xx): sample after sample, each with four
lane slots (lane r = RX r, zero when RX r is disabled); complex: I of the four lanes, then
their Q. Real ADC output: the I words only. The waveform comes from the mmWave SDK CLI
`.cfg` (profileCfg, chirpCfg, frameCfg, channelCfg, adcCfg) or the JSON equivalent
(`Dca1000Config`); the parameter mapping is in docs/import.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from core.parsing import JsonTooDeep, first_error, loads_json
from signatures.errors import SignaturesError
from signatures.importers.dwell import Dwell, analytic_half_rate, radar_config
from signatures.radar import RadarConfig

__all__ = ["AdcFormat", "Channels", "Chirp", "Dca1000Config", "Frame", "Profile", "Selection", "deinterleave",
           "dwells", "load_config", "parse_cfg", "plan"]

LANES = (2, 4)
#: Config files are small; a larger one is not a config.
MAX_CONFIG_BYTES = 1 << 20
_ADC_BITS = {0: 12, 1: 14, 2: 16}
_ADC_OUTPUT = {0: "real", 1: "complex1x", 2: "complex2x"}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Profile(_Strict):
    """profileCfg: one chirp profile (TI units: GHz, us, MHz/us, ksps)."""

    profile_id: int = Field(default=0, ge=0, le=3)
    start_freq_ghz: float = Field(gt=0, le=1000)
    idle_time_us: float = Field(ge=0)
    adc_start_time_us: float = Field(ge=0)
    ramp_end_time_us: float = Field(gt=0)
    freq_slope_mhz_per_us: float = Field(gt=0)
    num_adc_samples: int = Field(ge=2, le=65535)
    dig_out_sample_rate_ksps: float = Field(gt=0)


class Chirp(_Strict):
    """chirpCfg: chirps start_idx..end_idx use a profile, with per-chirp variations."""

    start_idx: int = Field(ge=0, le=511)
    end_idx: int = Field(ge=0, le=511)
    profile_id: int = Field(default=0, ge=0, le=3)
    start_freq_var_mhz: float = 0.0
    freq_slope_var_khz_per_us: float = 0.0
    idle_time_var_us: float = 0.0
    adc_start_time_var_us: float = 0.0
    tx_enable: int = Field(ge=1, le=7)


class Frame(_Strict):
    """frameCfg: each frame runs chirps chirp_start_idx..chirp_end_idx num_loops times."""

    chirp_start_idx: int = Field(ge=0, le=511)
    chirp_end_idx: int = Field(ge=0, le=511)
    num_loops: int = Field(ge=1, le=255)
    num_frames: int = Field(ge=0, le=65535)  # 0: until stopped
    frame_periodicity_ms: float = Field(gt=0)


class Channels(_Strict):
    """channelCfg: RX and TX enable bitmasks."""

    rx_enable: int = Field(ge=1, le=15)
    tx_enable: int = Field(ge=1, le=7)


class AdcFormat(_Strict):
    """adcCfg: ADC bits and output format (real, or complex I/Q at the digital output rate)."""

    bits: Literal[12, 14, 16] = 16
    output: Literal["real", "complex1x", "complex2x"] = "complex1x"

    @property
    def complex(self) -> bool:
        return self.output != "real"


class Dca1000Config(_Strict):
    """The waveform of a capture: the JSON form of the SDK `.cfg` (docs/import.md)."""

    profiles: list[Profile] = Field(min_length=1)
    chirps: list[Chirp] = Field(min_length=1)
    frame: Frame
    channels: Channels
    adc: AdcFormat = AdcFormat()

    @model_validator(mode="after")
    def _consistent(self) -> "Dca1000Config":
        ids = [p.profile_id for p in self.profiles]
        if len(set(ids)) != len(ids):
            raise ValueError("profileCfg: a profile id is defined twice")
        for k in range(self.frame.chirp_start_idx, self.frame.chirp_end_idx + 1):
            if sum(c.start_idx <= k <= c.end_idx for c in self.chirps) != 1:
                raise ValueError(f"chirpCfg: chirp {k} of the frame must be defined exactly once")
        for c in self.chirps:
            if c.start_idx > c.end_idx:
                raise ValueError(f"chirpCfg: start index {c.start_idx} > end index {c.end_idx}")
            if c.profile_id not in ids:
                raise ValueError(f"chirpCfg: profile {c.profile_id} is not defined by a profileCfg")
        if self.frame.chirp_start_idx > self.frame.chirp_end_idx:
            raise ValueError("frameCfg: chirp start index > chirp end index")
        for p in self.profiles:
            sampled_us = p.num_adc_samples / p.dig_out_sample_rate_ksps * 1e3
            if p.adc_start_time_us + sampled_us > p.ramp_end_time_us + 1e-9:
                raise ValueError(f"profileCfg {p.profile_id}: ADC start {p.adc_start_time_us:g} us + sampling "
                                 f"{sampled_us:g} us exceeds the ramp end time {p.ramp_end_time_us:g} us")
        return self

    def chirp(self, k: int) -> Chirp:
        return next(c for c in self.chirps if c.start_idx <= k <= c.end_idx)

    def profile(self, chirp: Chirp) -> Profile:
        return next(p for p in self.profiles if p.profile_id == chirp.profile_id)

    @property
    def loop(self) -> range:
        """The chirp indices of one loop, in transmission order."""
        return range(self.frame.chirp_start_idx, self.frame.chirp_end_idx + 1)

    def chirp_period_s(self, k: int) -> float:
        c = self.chirp(k)
        p = self.profile(c)
        return (p.idle_time_us + c.idle_time_var_us + p.ramp_end_time_us) * 1e-6

    @property
    def rx(self) -> tuple[int, ...]:
        """Enabled RX, by physical index."""
        return tuple(r for r in range(4) if self.channels.rx_enable >> r & 1)


# --- the SDK CLI .cfg ----------------------------------------------------------------

_CFG_FIELDS = {
    "profileCfg": (14, lambda v: {"profiles": dict(
        profile_id=int(v[0]), start_freq_ghz=v[1], idle_time_us=v[2], adc_start_time_us=v[3],
        ramp_end_time_us=v[4], freq_slope_mhz_per_us=v[7], num_adc_samples=int(v[9]),
        dig_out_sample_rate_ksps=v[10])}),
    "chirpCfg": (8, lambda v: {"chirps": dict(
        start_idx=int(v[0]), end_idx=int(v[1]), profile_id=int(v[2]), start_freq_var_mhz=v[3],
        freq_slope_var_khz_per_us=v[4], idle_time_var_us=v[5], adc_start_time_var_us=v[6], tx_enable=int(v[7]))}),
    "frameCfg": (7, lambda v: {"frame": dict(
        chirp_start_idx=int(v[0]), chirp_end_idx=int(v[1]), num_loops=int(v[2]), num_frames=int(v[3]),
        frame_periodicity_ms=v[4])}),
    "channelCfg": (3, lambda v: {"channels": dict(rx_enable=int(v[0]), tx_enable=int(v[1]))}),
    "adcCfg": (2, lambda v: {"adc": dict(bits=_ADC_BITS.get(int(v[0]), -1), output=_ADC_OUTPUT.get(int(v[1]), "?"))}),
}
#: Commands that change the frame structure in ways this importer does not model.
_REFUSED = {"advFrameCfg": "advanced frame configurations (subframes)", "subFrameCfg": "subframes"}


def parse_cfg(text: str, name: str = "config") -> Dca1000Config:
    """The mmWave SDK CLI configuration (one command per line, `%` comments). Commands
    other than the five that define the raw data are ignored; profileCfg and chirpCfg may
    repeat. One-line errors name the line."""
    doc: dict[str, object] = {"profiles": [], "chirps": []}
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.split("%", 1)[0].strip()
        if not line:
            continue
        cmd, *args = line.split()
        if cmd in _REFUSED:
            raise SignaturesError(f"{name} line {n}: {cmd}: {_REFUSED[cmd]} are not supported")
        if cmd == "dfeDataOutputMode" and args and args[0] != "1":
            raise SignaturesError(f"{name} line {n}: dfeDataOutputMode {args[0]}: only frame-based chirps (1) "
                                  f"are supported")
        if cmd == "bpmCfg" and len(args) > 1 and args[1] not in ("0", "0.0"):
            raise SignaturesError(f"{name} line {n}: bpmCfg: BPM-MIMO (TX phase coding) is not supported")
        if cmd not in _CFG_FIELDS:
            continue
        count, build = _CFG_FIELDS[cmd]
        if len(args) < count:
            raise SignaturesError(f"{name} line {n}: {cmd}: expected {count} values, got {len(args)}")
        try:
            values = [float(a) for a in args[:count]]
        except ValueError:
            raise SignaturesError(f"{name} line {n}: {cmd}: not a number in {' '.join(args[:count])!r}") from None
        if not all(math.isfinite(v) for v in values):
            raise SignaturesError(f"{name} line {n}: {cmd}: values must be finite")
        for key, value in build(values).items():
            if key in ("profiles", "chirps"):
                doc[key].append(value)  # type: ignore[union-attr]
            elif key in doc:
                raise SignaturesError(f"{name} line {n}: {cmd} given twice")
            else:
                doc[key] = value
    missing = [c for c, k in (("profileCfg", "profiles"), ("chirpCfg", "chirps"), ("frameCfg", "frame"),
                              ("channelCfg", "channels")) if not doc.get(k)]
    if missing:
        raise SignaturesError(f"{name}: missing {', '.join(missing)}")
    return _validated(doc, name)


def _validated(doc: object, name: str) -> Dca1000Config:
    try:
        return Dca1000Config.model_validate(doc)
    except ValidationError as exc:
        loc, msg, given = first_error(exc)
        where = f" {loc}" if loc else ""
        got = f" (got {given!r})" if loc and not isinstance(given, (dict, list)) else ""
        raise SignaturesError(f"{name}:{where}: {msg}{got}") from None


def load_config(path: Path) -> Dca1000Config:
    """A `.cfg` (SDK CLI text) or `.json` (`Dca1000Config`) file."""
    try:
        if path.stat().st_size > MAX_CONFIG_BYTES:
            raise SignaturesError(f"{path}: larger than {MAX_CONFIG_BYTES} bytes; not a radar configuration")
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SignaturesError(f"{path}: cannot read ({getattr(exc, 'strerror', None) or exc})") from None
    if path.suffix.lower() == ".json":
        try:
            doc = loads_json(text)
        except JsonTooDeep as exc:
            raise SignaturesError(f"{path}: {exc}") from None
        except ValueError as exc:
            raise SignaturesError(f"{path}: not valid JSON ({exc})") from None
        return _validated(doc, str(path))
    return parse_cfg(text, str(path))


# --- the raw layout ------------------------------------------------------------------

def deinterleave(words: np.ndarray, n_chirps: int, n_slots: int, n_samples: int, lanes: int,
                 complex_: bool) -> np.ndarray:
    """int16 words of `n_chirps` chirps -> (n_chirps, n_slots, n_samples), complex64 when
    `complex_` else int16. `n_slots`: the enabled RX with 2 lanes, always 4 with 4 lanes."""
    per = 2 if complex_ else 1
    if words.size != n_chirps * n_slots * n_samples * per:
        raise SignaturesError(f"raw data: {words.size} words do not hold {n_chirps} chirps x {n_slots} RX x "
                              f"{n_samples} samples{' x (I, Q)' if complex_ else ''}")
    if lanes == 2:
        if not complex_:
            return words.reshape(n_chirps, n_slots, n_samples)
        if (n_slots * n_samples) % 2:
            raise SignaturesError("raw data: 2-lane complex data pair samples; RX x samples must be even")
        g = words.reshape(-1, 4).astype(np.float32)
        z = (g[:, :2] + 1j * g[:, 2:]).astype(np.complex64)  # I(k) I(k+1) Q(k) Q(k+1)
        return z.reshape(n_chirps, n_slots, n_samples)
    if lanes == 4:
        if not complex_:
            return words.reshape(n_chirps, n_samples, n_slots).transpose(0, 2, 1)
        g = words.reshape(n_chirps, n_samples, 2, n_slots).astype(np.float32)
        z = (g[:, :, 0, :] + 1j * g[:, :, 1, :]).astype(np.complex64)  # I of each lane, then Q
        return z.transpose(0, 2, 1)
    raise SignaturesError(f"--lanes: {lanes} (expected one of {', '.join(map(str, LANES))})")


def _sign_extend(words: np.ndarray, bits: int) -> np.ndarray:
    """12/14-bit ADC words as TI's readDCA1000.m reads them: values above 2^(bits-1)-1 are
    negative."""
    if bits == 16:
        return words
    w = words.astype(np.int32)
    w[w > 2 ** (bits - 1) - 1] -= 2 ** bits
    return w.astype(np.int16)


# --- from the configuration to our waveform ------------------------------------------

class Selection(_Strict):
    """What to take out of a capture (the CLI's options)."""

    lanes: Literal[2, 4] = 2
    rx: int | None = Field(default=None, ge=0, le=3)  # physical RX; None: the lowest enabled
    tx: int | None = Field(default=None, ge=0, le=2)  # the loop's chirp on this TX; None: the loop's first
    frame: int | None = Field(default=None, ge=0)  # one frame; None: all
    frames_per_dwell: int = Field(default=1, ge=1)
    iq_swap: bool = False  # Q word before I (a device with adcbufCfg IQSwap 1)


class Plan(_Strict):
    """The capture's layout and what becomes of it."""

    config: RadarConfig
    chirp_in_loop: int  # position of the selected chirp within a loop
    chirps_per_loop: int
    rx_slot: int
    n_slots: int
    frame_words: int
    n_frames: int  # in the file
    first_frame: int
    n_dwells: int
    frame_period_s: float


def _waveform(cfg: Dca1000Config, k: int) -> RadarConfig:
    """Our attributes for loop chirp k (docs/import.md): carrier = start frequency + slope x
    ADC start time, ramp = samples / fs, bandwidth = slope x ramp, PRI = the loop's
    duration (one chirp per loop is kept)."""
    c = cfg.chirp(k)
    p = cfg.profile(c)
    slope = (p.freq_slope_mhz_per_us + c.freq_slope_var_khz_per_us * 1e-3) * 1e12  # Hz/s
    fs = p.dig_out_sample_rate_ksps * 1e3
    ramp = p.num_adc_samples / fs
    carrier = p.start_freq_ghz * 1e9 + c.start_freq_var_mhz * 1e6 + slope * (p.adc_start_time_us
                                                                             + c.adc_start_time_var_us) * 1e-6
    pri = sum(cfg.chirp_period_s(j) for j in cfg.loop)
    rate = fs if cfg.adc.complex else fs / 2  # real IF is made complex at half the rate
    return radar_config("config", carrier_hz=carrier, bandwidth_hz=slope * ramp, ramp_s=ramp, pri_s=pri,
                        sample_rate_hz=rate)


def _chirp_for_tx(cfg: Dca1000Config, tx: int | None) -> int:
    if tx is None:
        return cfg.frame.chirp_start_idx
    if not cfg.channels.tx_enable >> tx & 1:
        raise SignaturesError(f"--tx {tx}: TX {tx} is not enabled (channelCfg TX mask {cfg.channels.tx_enable})")
    for k in cfg.loop:
        if cfg.chirp(k).tx_enable == 1 << tx:
            return k
    raise SignaturesError(f"--tx {tx}: no chirp of the loop transmits on TX {tx} alone")


def _rx_slot(cfg: Dca1000Config, rx: int | None, lanes: int) -> tuple[int, int]:
    """(slot of the selected RX in the data, slots per sample or chirp)."""
    enabled = cfg.rx
    rx = enabled[0] if rx is None else rx
    if rx not in enabled:
        raise SignaturesError(f"--rx {rx}: RX {rx} is not enabled (channelCfg RX mask {cfg.channels.rx_enable}: "
                              f"RX {', '.join(map(str, enabled))})")
    return (enabled.index(rx), len(enabled)) if lanes == 2 else (rx, 4)


def plan(cfg: Dca1000Config, total_bytes: int, sel: Selection) -> Plan:
    """Check the capture's size against the configuration and lay out the dwells."""
    k = _chirp_for_tx(cfg, sel.tx)
    config = _waveform(cfg, k)
    p = cfg.profile(cfg.chirp(k))
    if any(cfg.profile(cfg.chirp(j)).num_adc_samples != p.num_adc_samples for j in cfg.loop):
        raise SignaturesError("config: the loop's chirps use profiles with different sample counts")
    slot, n_slots = _rx_slot(cfg, sel.rx, sel.lanes)
    loop = len(cfg.loop)
    frame_words = cfg.frame.num_loops * loop * n_slots * p.num_adc_samples * (2 if cfg.adc.complex else 1)
    frame_bytes = 2 * frame_words
    n_frames, rest = divmod(total_bytes, frame_bytes)
    layout = (f"{cfg.frame.num_loops} loops x {loop} chirps x {n_slots} RX x {p.num_adc_samples} samples"
              f"{' x (I, Q)' if cfg.adc.complex else ''} x 2 bytes = {frame_bytes} bytes per frame")
    if rest or n_frames == 0:
        raise SignaturesError(f"raw data: {total_bytes} bytes are not a whole number of frames ({layout}): "
                              f"a truncated capture, or a config that does not match it")
    if cfg.frame.num_frames and n_frames != cfg.frame.num_frames:
        what = "truncated capture" if n_frames < cfg.frame.num_frames else "more data than configured"
        raise SignaturesError(f"raw data: {n_frames} frames, frameCfg says {cfg.frame.num_frames} ({what}; {layout})")
    period = cfg.frame.frame_periodicity_ms * 1e-3
    active = cfg.frame.num_loops * config.pri_s
    if period < active * (1 - 1e-9):
        raise SignaturesError(f"frameCfg: frame period {period * 1e3:g} ms is shorter than its chirps "
                              f"({active * 1e3:g} ms)")
    if sel.frames_per_dwell > 1 and not math.isclose(period, active, rel_tol=1e-6):
        raise SignaturesError(f"--frames-per-dwell {sel.frames_per_dwell}: frames are {period * 1e3:g} ms apart but "
                              f"chirp for {active * 1e3:g} ms; a dwell spans frames only when the radar chirps "
                              f"without a gap")
    if sel.frame is not None:
        if sel.frame + sel.frames_per_dwell > n_frames:
            raise SignaturesError(f"--frame {sel.frame}: the capture holds frames 0..{n_frames - 1}")
        first, n_dwells = sel.frame, 1
    else:
        first, n_dwells = 0, n_frames // sel.frames_per_dwell
        if n_dwells == 0:
            raise SignaturesError(f"--frames-per-dwell {sel.frames_per_dwell}: the capture holds {n_frames} frames")
    return Plan(config=config, chirp_in_loop=k - cfg.frame.chirp_start_idx, chirps_per_loop=loop, rx_slot=slot,
                n_slots=n_slots, frame_words=frame_words, n_frames=n_frames, first_frame=first, n_dwells=n_dwells,
                frame_period_s=period)


class _Concatenated:
    """The capture's files read as one byte stream (the DCA1000 splits long captures into
    `_Raw_0.bin`, `_Raw_1.bin`, ... at a size, not at frame boundaries)."""

    def __init__(self, paths: Sequence[Path]) -> None:
        self.paths = list(paths)
        self.sizes = []
        for path in self.paths:
            try:
                if not path.is_file():
                    raise SignaturesError(f"{path}: not a regular file")
                self.sizes.append(path.stat().st_size)
            except OSError as exc:
                raise SignaturesError(f"{path}: cannot open ({exc.strerror or exc})") from None

    @property
    def size(self) -> int:
        return sum(self.sizes)

    def words(self, offset: int, count: int) -> np.ndarray:
        """`count` little-endian int16 words from byte `offset`."""
        out = bytearray()
        for path, size in zip(self.paths, self.sizes):
            if offset >= size:
                offset -= size
                continue
            take = min(size - offset, 2 * count - len(out))
            try:
                with path.open("rb") as fh:
                    fh.seek(offset)
                    out += fh.read(take)
            except OSError as exc:
                raise SignaturesError(f"{path}: cannot read ({exc.strerror or exc})") from None
            offset = 0
            if len(out) == 2 * count:
                break
        if len(out) != 2 * count:
            raise SignaturesError("raw data: the files shrank while being read")
        return np.frombuffer(bytes(out), dtype="<i2")


def dwells(paths: Sequence[Path], cfg: Dca1000Config, sel: Selection) -> tuple[Plan, Iterator[Dwell]]:
    """The plan (sizes checked) and the dwells, read frame by frame."""
    source = _Concatenated(paths)
    if source.size % 2:
        raise SignaturesError(f"raw data: {source.size} bytes are not whole int16 words (truncated capture)")
    pl = plan(cfg, source.size, sel)

    def frames(first: int, count: int) -> np.ndarray:
        words = source.words(first * pl.frame_words * 2, count * pl.frame_words)
        words = _sign_extend(words, cfg.adc.bits)
        n_chirps = count * cfg.frame.num_loops * pl.chirps_per_loop
        n = cfg.profile(cfg.chirp(cfg.frame.chirp_start_idx + pl.chirp_in_loop)).num_adc_samples
        cube = deinterleave(words, n_chirps, pl.n_slots, n, sel.lanes, cfg.adc.complex)
        iq = cube[pl.chirp_in_loop::pl.chirps_per_loop, pl.rx_slot, :]
        if sel.iq_swap and cfg.adc.complex:
            iq = (iq.imag + 1j * iq.real).astype(np.complex64)
        return np.ascontiguousarray(iq) if cfg.adc.complex else analytic_half_rate(iq.astype(np.float32))

    def generate() -> Iterator[Dwell]:
        for d in range(pl.n_dwells):
            first = pl.first_frame + d * sel.frames_per_dwell
            before = cfg.loop[:pl.chirp_in_loop]  # the loop's chirps sent before the selected one
            offset = first * pl.frame_period_s + sum(cfg.chirp_period_s(j) for j in before)
            yield Dwell(frames(first, sel.frames_per_dwell), pl.config, "if", offset, f"frame_{first:06d}")

    return pl, generate()

