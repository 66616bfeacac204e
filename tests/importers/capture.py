"""Test-side writers of foreign captures, written from the documented layouts (not from the
importers): a TI DCA1000EVM raw file (SWRA581B / readDCA1000.m) and its mmWave SDK `.cfg`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from signatures.radar import RadarConfig


def quantise(iq: np.ndarray, peak: float) -> tuple[np.ndarray, float]:
    """Complex samples as int16 I and Q using 90 % of the ADC range: (int16 complex pairs as
    a complex128 array of integers, the scale applied)."""
    scale = 0.9 * 32767 / max(float(np.max(np.abs(iq.real))), float(np.max(np.abs(iq.imag))), peak)
    return np.round(iq.real * scale) + 1j * np.round(iq.imag * scale), scale


def raw_words(cube: np.ndarray, lanes: int, complex_: bool) -> np.ndarray:
    """int16 words of a (chirps, RX slots, samples) cube of integer-valued samples, in the
    order TI documents: 2 lanes = per chirp the RX one after the other, complex samples in
    groups I(k) I(k+1) Q(k) Q(k+1); 4 lanes = per chirp sample after sample, four lane slots
    each, complex = the four I words then the four Q words."""
    words: list[float] = []
    n_chirps, n_slots, n_samples = cube.shape
    if lanes == 2:
        flat = cube.reshape(-1)
        if not complex_:
            return np.asarray(flat.real, dtype="<i2")
        for k in range(0, flat.size, 2):
            words += [flat[k].real, flat[k + 1].real, flat[k].imag, flat[k + 1].imag]
    else:
        for c in range(n_chirps):
            for s in range(n_samples):
                lanes_at = cube[c, :, s]
                words += list(lanes_at.real) + (list(lanes_at.imag) if complex_ else [])
    return np.asarray(words, dtype="<i2")


def sdk_cfg(config: RadarConfig, n_samples: int, loops: int, frames: int, frame_period_s: float,
            rx_mask: int = 1, tx_masks: tuple[int, ...] = (1,), adc_start_s: float = 0.0,
            real: bool = False) -> str:
    """An mmWave SDK CLI profile whose sampled sweep is `config`'s: start frequency = carrier -
    slope x ADC start, rampEnd = ADC start + samples / fs, idle = (PRI / chirps per loop) - rampEnd."""
    slope = config.slope_hz_per_s
    fs = config.sample_rate_hz * (2 if real else 1)
    n_adc = n_samples * (2 if real else 1)
    ramp_end = adc_start_s + n_adc / fs
    idle = config.pri_s / len(tx_masks) - ramp_end
    assert idle >= -1e-12, "the waveform leaves no time for the ADC start"
    lines = [
        "% written by tests/importers/capture.py",
        "sensorStop", "flushCfg", "dfeDataOutputMode 1",
        f"channelCfg {rx_mask} {sum(tx_masks)} 0",
        f"adcCfg 2 {0 if real else 1}",
        "adcbufCfg -1 0 1 1 1",
        f"profileCfg 0 {(config.carrier_hz - slope * adc_start_s) / 1e9!r} {max(idle, 0.0) * 1e6!r} "
        f"{adc_start_s * 1e6!r} {ramp_end * 1e6!r} 0 0 {slope / 1e12!r} 1 {n_adc} {fs / 1e3!r} 0 0 30",
        *[f"chirpCfg {i} {i} 0 0 0 0 0 {m}" for i, m in enumerate(tx_masks)],
        f"frameCfg 0 {len(tx_masks) - 1} {loops} {frames} {frame_period_s * 1e3!r} 1 0",
        "bpmCfg -1 0 0 1",
        "lowPower 0 0", "guiMonitor -1 1 0 0 0 0 0", "sensorStart",
    ]
    return "\n".join(lines) + "\n"


def write_capture(path: Path, words: np.ndarray, split_at: int | None = None) -> list[Path]:
    """The words as one raw file, or split into _Raw_0/_Raw_1 at a byte offset (as the DCA1000
    does for long captures)."""
    data = words.astype("<i2").tobytes()
    if split_at is None:
        path.write_bytes(data)
        return [path]
    first, second = path.with_name(path.stem + "_Raw_0.bin"), path.with_name(path.stem + "_Raw_1.bin")
    first.write_bytes(data[:split_at])
    second.write_bytes(data[split_at:])
    return [first, second]


__all__ = ["quantise", "raw_words", "sdk_cfg", "write_capture"]
