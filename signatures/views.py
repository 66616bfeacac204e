"""The paper's figures 2-6 as arrays: RD map, spectrogram, mean spectrogram, Doppler
intensity and cadence-velocity diagram of one return (the plotting lives in the CLI)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from signatures.dsp import rd
from signatures.dsp import timefreq as tf
from signatures.features import GATE_BINS, extract_iq


@dataclass(frozen=True)
class Views:
    rd_map: rd.RdMap  # whole recorded window, clutter suppressed
    spectrogram: tf.Spectrogram  # at the target's range gate
    doppler_profile: np.ndarray  # Doppler intensity over the gate (full resolution)
    cadence: tf.Cadence
    detected: bool


def views(recording, clutter_suppression: bool = True) -> Views:
    """Everything the plots show, computed the same way as the features. A `range` or `cw`
    cube already is a range spectrum (docs/format.md): no range FFT, only the clutter's mean
    removed (a CW return's map is its one channel's Doppler spectrum)."""
    res = extract_iq(recording.iq, recording.config, clutter_suppression=clutter_suppression,
                     domain=recording.domain)
    prep = rd.prepare(recording.iq)
    if recording.domain == "if":
        spectrum = rd.range_fft(prep.iq, clutter_suppression)
    else:
        spectrum = prep.iq - prep.iq.mean(axis=0, keepdims=True) if clutter_suppression else prep.iq
    full = rd.rd_map(spectrum, recording.config)
    lo, hi = res.gate if res.gate[1] > res.gate[0] else (0, GATE_BINS)
    slow = spectrum[:, lo:hi]
    spec = tf.spectrogram(slow, recording.config, *tf.stft_params(recording.config, recording.n_chirps))
    return Views(full, spec, full.power[:, lo:hi].sum(axis=1), tf.cadence(spec), res.detected)
