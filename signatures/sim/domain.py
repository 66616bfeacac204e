"""What a range-domain or CW radar would deliver for a simulated IF cube, and its waveform.

Pure functions (arrays and configurations in, the same out): `to_domain` converts a
dechirped IF cube (chirps x samples, docs/format.md) into the `/iq` of another `domain`;
`range_config` and `cw_config` are the FMCW-equivalent `RadarConfig`s the importers write
for those domains, so that every range and Doppler formula of the pipeline keeps working.
The conventions and the CW choice are justified in docs/signal-model.md ("Other domains").
"""

from __future__ import annotations

import numpy as np

from signatures.dsp import rd
from signatures.errors import SignaturesError
from signatures.radar import C, RadarConfig
from signatures.recording import DOMAINS, Recording

__all__ = ["DOMAINS", "as_recorded", "cw_config", "range_config", "to_domain"]


def to_domain(iq_if: np.ndarray, config: RadarConfig, domain: str) -> np.ndarray:
    """The `/iq` a radar of `domain` records for the scene behind the IF cube `iq_if`.

    `if`: the cube itself. `range`: the pipeline's own range FFT (`rd.range_fft`: Hann
    window of unit mean, no fftshift) without clutter suppression, (chirps x range bins).
    `cw`: the first fast-time sample of each chirp, (chirps x 1): by the signal model it is
    sum_i a_i exp(j*2*pi*2*f_c*R_i/c) plus that sample's noise, i.e. a CW measurement at
    the carrier `config.carrier_hz` sampled once per PRI, with every range and all the
    clutter in it. `config` is the waveform of `iq_if`: neither conversion needs more than
    the cube, but a caller always holds the pair, and the configuration the result is
    recorded under comes from it (`range_config`, `cw_config`).
    """
    cube = np.asarray(iq_if)
    if cube.ndim != 2 or cube.shape[0] < 1 or cube.shape[1] < 1:
        raise SignaturesError(f"IF cube must be 2-D (n_chirps, n_samples), got shape {cube.shape}")
    if domain not in DOMAINS:
        raise SignaturesError(f"unknown domain {domain!r} (known: {', '.join(DOMAINS)})")
    if domain == "if":
        return cube
    if domain == "range":
        return rd.range_fft(cube, suppress_clutter=False)
    return np.ascontiguousarray(cube[:, :1])


def range_config(carrier_hz: float, pri_s: float, range_bin_m: float, first_range_m: float,
                 n_bins: int) -> RadarConfig:
    """The FMCW waveform equivalent to range-compressed pulses: ramp = PRI, fs = n/ramp,
    bandwidth = c/(2*bin), so `range_bin_m(n_bins)` is the given bin and `range_offset_m`
    the first bin's range."""
    if n_bins < 1 or not range_bin_m > 0:
        raise SignaturesError(f"range bins: need n_bins >= 1 and a positive bin size, got {n_bins}, {range_bin_m}")
    return RadarConfig(carrier_hz=carrier_hz, bandwidth_hz=C / (2.0 * range_bin_m), ramp_s=pri_s, pri_s=pri_s,
                       sample_rate_hz=n_bins / pri_s, range_offset_m=first_range_m)


def cw_config(carrier_hz: float, pri_s: float) -> RadarConfig:
    """The FMCW waveform equivalent to CW Doppler IQ sampled every `pri_s`: one sample per
    ramp (ramp = PRI, fs = 1/PRI) and bandwidth 1/PRI, so the single range bin is c*PRI/2
    wide (every range the PRI could return); range offset 0. Only the carrier and the PRI
    carry information."""
    return RadarConfig(carrier_hz=carrier_hz, bandwidth_hz=1.0 / pri_s, ramp_s=pri_s, pri_s=pri_s,
                       sample_rate_hz=1.0 / pri_s, range_offset_m=0.0)


def as_recorded(rec: Recording, domain: str) -> Recording:
    """A simulated IF recording as a radar of `domain` records it (training sets for range and
    CW waveforms). The recording must already use that domain's equivalent waveform
    (`range_config`, `cw_config`): a CW waveform has one sample per chirp, which is its CW
    sample (`to_domain`), so only the cube's meaning changes, not its numbers."""
    from dataclasses import replace

    if domain == rec.domain:
        return rec
    if rec.domain != "if":
        raise SignaturesError(f"cannot convert a {rec.domain}-domain recording to {domain}")
    return replace(rec, iq=to_domain(rec.iq, rec.config, domain), domain=domain)
