"""The feature vector of one return and what goes with it: its fields, constants, the CNN patch.

`signatures.dsp.extraction` computes it (array-first: one return is a batch of one);
`signatures.features` is the public front of both. Exact definitions: docs/features.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from signatures.dsp import timefreq as tf
from signatures.radar import RadarConfig

if TYPE_CHECKING:
    from signatures.dsp.flash_spectrum import FlashCurve

#: Bump when feature values change: training-set caches key on it, and
#: tests/features/test_feature_version.py fails until it is bumped and its golden values updated.
FEATURE_VERSION = "14"
GATE_BINS = 5  # range bins of the slow-time gate (target +- 2: migration and Hann spread)
PATCH_SHAPE = (32, 32)  # (Doppler bands, range bins) of the CNN patch
PATCH_FLOOR_DB = -60.0
BODY_BINS = 3  # Doppler bins either side of the body line that count as "body"
MOVING_LINE_BINS = 6  # a moving body line's peak-to-median exceeds n_chirps / this (see _features)
#: A CW body line off zero Doppler has no mirror image this much (dB) as strong about zero; a hovering
#: rotor's lines come in pairs (simulated: flying >= 21 dB, hovering <= 9 dB)
MIRROR_DB = 15.0
#: An accelerating CW body's line is followed over this many sub-dwells (extraction._drifting_line),
#: within this many of their Doppler bins of the whole dwell's candidate (8 x 9.8 Hz at 5 kHz / 512).
SUB_DWELLS = 8
DRIFT_SUB_BINS = 8
DRIFT_MISSES = 1
#: A hovering target's range: the centroid of the clutter-suppressed range profile (above its
#: median) over the peak bin +- this many bins (`hover_range_bin`).
HOVER_CENTROID_BINS = 3
PEAK_PROMINENCE_DB = 6.0  # a significant Doppler peak rises this much above its surroundings
PEAK_ABOVE_NOISE_DB = 6.0  # ... and this much above the noise level
PEAK_PROFILE_BANDS = 128  # Doppler profile pooled to at most this many bands for peak counting
OCCUPANCY_DB = 6.0  # a Doppler bin is occupied when this much above the noise level
ALIAS_FRACTION = 0.95  # micro-Doppler reaching this share of the half band = aliased
PEAK_DB_FLOOR = -999.0  # peak amplitude of an all-zero cube
TINY = float(np.finfo(np.float32).tiny)
DB_PER_LN = np.float32(10.0 / math.log(10.0))


@dataclass(frozen=True)
class Features:
    """The feature vector, in its fixed order (`FEATURE_NAMES`); all finite floats."""

    # the paper's 11 (Eq. 12-21), in the paper's order
    mean_range_m: float
    mean_doppler_mps: float
    std_range_m: float
    std_doppler_mps: float
    par_db: float
    spectral_centroid_hz: float
    spectral_bandwidth_hz: float
    peak_amplitude_db: float
    num_peaks: float
    energy_ratio: float
    entropy: float
    # physical estimates and their one-sigma uncertainties
    range_m: float
    range_std_m: float
    radial_velocity_mps: float
    radial_velocity_std_mps: float
    flash_rate_hz: float
    flash_rate_std_hz: float
    rotor_rate_hz: float
    rotor_rate_std_hz: float
    rotor_count: float
    rotor_count_std: float
    tip_speed_mps: float
    tip_speed_std_mps: float
    blade_length_m: float
    blade_length_std_m: float
    tip_aliased: float
    # micro-Doppler / cadence descriptors
    flash_score: float
    flash_count: float
    flash_par_db: float
    doppler_occupancy: float
    cadence_peak_hz: float
    cadence_harmonic_ratio: float
    snr_db: float
    detected: float
    # the flash envelope's autocorrelation at 2, 4, ..., 30 ms (`signatures.dsp.envelope.LAGS_S`)
    flash_ac_2ms: float
    flash_ac_4ms: float
    flash_ac_6ms: float
    flash_ac_8ms: float
    flash_ac_10ms: float
    flash_ac_12ms: float
    flash_ac_14ms: float
    flash_ac_16ms: float
    flash_ac_18ms: float
    flash_ac_20ms: float
    flash_ac_22ms: float
    flash_ac_24ms: float
    flash_ac_26ms: float
    flash_ac_28ms: float
    flash_ac_30ms: float

    def as_array(self) -> np.ndarray:
        # the fields' values as they are (`astuple` would deep-copy each float first: ~20 us)
        return np.array([getattr(self, name) for name in FEATURE_NAMES], dtype=np.float32)


FEATURE_NAMES: tuple[str, ...] = tuple(f.name for f in fields(Features))
#: The flash envelope's autocorrelation, one per lag of `signatures.dsp.envelope.LAGS_S`.
ENVELOPE_FEATURES: tuple[str, ...] = tuple(n for n in FEATURE_NAMES if n.startswith("flash_ac_"))
#: What `quick=True` computes (the rest stay 0): the paper's 11 and the gate's physics that need
#: no slow-time estimator, no STFT and no CNN patch. Same values as the full extraction.
QUICK_FEATURES: tuple[str, ...] = FEATURE_NAMES[:15] + ("tip_speed_mps", "tip_speed_std_mps", "tip_aliased",
                                                         "doppler_occupancy", "snr_db", "detected")


@dataclass(frozen=True)
class FeatureResult:
    """What `extract` returns: detection flag, named features, the CNN patch, the gate.

    The patch is computed on first use of `rd_patch` (~0.5 ms in `paper`): a check runs the
    CNN only when the ensemble is unsure, so most checks never build it.
    """

    detected: bool
    features: Features
    make_patch: Callable[[], np.ndarray]
    gate: tuple[int, int]  # [lo, hi) range bins the slow-time work ran on
    names: tuple[str, ...] = field(default=FEATURE_NAMES)
    #: physical estimates only 1:1 verification reads (`signatures.classify.verify`), not classifier
    #: inputs: the bundles' feature vector stays as trained. Empty where not measured.
    physics: Mapping[str, float] = field(default_factory=dict)
    #: a long dwell's flash score at every candidate rate (`flash_spectrum.FlashCurve`): a track
    #: reads its dwells at the track's rate from it; None where the dwell had no envelope search
    flash_curve: "FlashCurve | None" = None

    @cached_property
    def rd_patch(self) -> np.ndarray:
        """float32 PATCH_SHAPE, log power in [0, 1], body Doppler centred."""
        return self.make_patch()

    def as_array(self) -> np.ndarray:
        return self.features.as_array()

    @property
    def range_m(self) -> float:
        return self.features.range_m

    @property
    def radial_velocity_mps(self) -> float:
        return self.features.radial_velocity_mps


def physics_estimates(rotors_seen: float, rotors_seen_std: float, lower_bound: bool = False,
                      known: bool = True) -> dict[str, float]:
    """`FeatureResult.physics` from its estimates (one place for the single and batch paths).
    `lower_bound`: the count is of the rotors visible above the noise (a long dwell,
    `signatures.dsp.rotor_lines`), marked `rotors_lower_bound` = 1 for the verification. `known`
    False: the dwell gives no count (`rotor_lines.count_known`), marked `rotors_unknown` = 1 with
    rotors_seen 0 and no std, on which the verification abstains."""
    out = {"rotors_seen": float(rotors_seen), "rotors_seen_std": float(rotors_seen_std)}
    if lower_bound:
        out["rotors_lower_bound"] = 1.0
    if not known:
        out.update(rotors_seen=0.0, rotors_seen_std=0.0, rotors_unknown=1.0)
    return out


def hover_range_bin(profile: np.ndarray, peak_bin: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """Per row of (rows, bins) range profiles: the hub range (fractional bin) of a hovering
    target. Clutter suppression removes its body with the clutter, leaving the blades, whose
    intra-chirp Doppler moves each blade's energy up to ~1.5 bins (`paper`) to one side or the
    other of its hub: the profile's peak then sits on one blade side, while the centroid of
    the power above the median (`noise`) over the peak +- HOVER_CENTROID_BINS balances the
    two sides."""
    n_bins = profile.shape[1]
    cols = peak_bin[:, None] + np.arange(-HOVER_CENTROID_BINS, HOVER_CENTROID_BINS + 1)[None, :]
    inside = (cols >= 0) & (cols < n_bins)
    p = np.take_along_axis(profile, np.clip(cols, 0, n_bins - 1), axis=1).astype(np.float64)
    w = np.where(inside, np.maximum(p - noise[:, None], 0.0), 0.0)
    total = w.sum(axis=1)
    centroid = (cols * w).sum(axis=1) / np.maximum(total, TINY)
    return np.where(total > 0, centroid, peak_bin.astype(np.float64))


def window(centre: int, size: int, n: int) -> tuple[int, int]:
    size = min(size, n)
    lo = min(max(0, centre - size // 2), n - size)
    return lo, lo + size


def patch(spectrum: np.ndarray, config: RadarConfig, peak_bin: int, body_idx: float,
           fft_backend: str | None = None) -> np.ndarray:
    """CNN input: Doppler x range power of PATCH_SHAPE[1] range bins around the target, in
    PATCH_SHAPE[0] Doppler bands (Welch: Hann frames of PATCH_SHAPE[0] chirps, averaged;
    as informative as pooling a full-resolution spectrum into bands and several times
    cheaper), rolled so the body's band is the middle one; dB below the patch maximum,
    floored at PATCH_FLOOR_DB and mapped to [0, 1]."""
    n_dop, n_rng = PATCH_SHAPE
    n_chirps, n_bins = spectrum.shape
    lo, hi = window(peak_bin, n_rng, n_bins)
    spec = tf.spectrogram(spectrum[:, lo:hi], config, n_dop, n_dop, per_column=True, fft_backend=fft_backend)
    bands = spec.power.mean(axis=0)  # (n_dop, range)
    body_band = int(round((body_idx - n_chirps // 2) * n_dop / n_chirps))
    bands = np.roll(bands, -body_band, axis=0)
    out = np.zeros(PATCH_SHAPE, dtype=np.float32)
    out[:, :bands.shape[1]] = to_unit_db(bands)
    return out


def no_patch() -> np.ndarray:
    return np.zeros(PATCH_SHAPE, np.float32)


def to_unit_db(p: np.ndarray) -> np.ndarray:
    peak = max(float(p.max()), TINY)
    with np.errstate(divide="ignore"):
        db = np.log(np.maximum(p / np.float32(peak), np.float32(TINY))) * DB_PER_LN
    return ((np.maximum(db, np.float32(PATCH_FLOOR_DB)) - np.float32(PATCH_FLOOR_DB))
            / np.float32(-PATCH_FLOOR_DB)).astype(np.float32)


def empty(config: RadarConfig, n_chirps: int, n_bins: int, within: tuple[int, int] | None) -> FeatureResult:
    """An all-zero cube: nothing detected, every feature 0 but the peak amplitude floor."""
    values = {name: 0.0 for name in FEATURE_NAMES}
    values["peak_amplitude_db"] = PEAK_DB_FLOOR
    values["snr_db"] = -100.0
    centre = (within[0] + within[1]) // 2 if within else n_bins // 2
    return FeatureResult(False, Features(**values), no_patch,
                         window(centre, GATE_BINS, n_bins))
