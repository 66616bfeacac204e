"""Micro-Doppler features of one recorded return: the paper's 11 plus physical estimates.

`extract(recording)` is the entry point (`extract_iq(iq, config)` for a bare cube).
Only the range FFT and the range profile touch the whole cube; everything in
slow time runs on the target's range gate (detected, or around a caller's
expected range). Exact definitions: docs/features.md.

Numerics: the cube is first scaled by an exact power of two (`rd.prepare`), so
every feature but `peak_amplitude_db` is independent of the IQ scale and no
power is ever squared out of float32 range; divisions use `max(x, tiny)`; logs
are floored. Everything is float32 except scalar bookkeeping (absolute ranges,
the peak amplitude's exponent) done in Python floats.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields, replace
from functools import cached_property

import numpy as np

from signatures import estimators as est
from signatures import fft as _fft
from signatures import rd
from signatures import timefreq as tf
from signatures.errors import SignaturesError
from signatures.radar import RadarConfig
from signatures.recording import DOMAINS
from signatures.stats import median

__all__ = ["FEATURE_NAMES", "FEATURE_VERSION", "GATE_BINS", "PATCH_SHAPE", "QUICK_FEATURES", "FeatureResult",
           "Features", "extract", "extract_iq", "physics_estimates"]

#: Bump when feature values change: training-set caches key on it, and
#: tests/features/test_feature_version.py fails until it is bumped and its golden values updated.
FEATURE_VERSION = "4"
GATE_BINS = 5  # range bins of the slow-time gate (target +- 2: migration and Hann spread)
PATCH_SHAPE = (32, 32)  # (Doppler bands, range bins) of the CNN patch
PATCH_FLOOR_DB = -60.0
BODY_BINS = 3  # Doppler bins either side of the body line that count as "body"
MOVING_LINE_BINS = 6  # a moving body line's peak-to-median exceeds n_chirps / this (see _features)
#: A hovering target's range: the centroid of the clutter-suppressed range profile (above its
#: median) over the peak bin +- this many bins (`hover_range_bin`).
HOVER_CENTROID_BINS = 3
PEAK_PROMINENCE_DB = 6.0  # a significant Doppler peak rises this much above its surroundings
PEAK_ABOVE_NOISE_DB = 6.0  # ... and this much above the noise level
PEAK_PROFILE_BANDS = 128  # Doppler profile pooled to at most this many bands for peak counting
OCCUPANCY_DB = 6.0  # a Doppler bin is occupied when this much above the noise level
ALIAS_FRACTION = 0.95  # micro-Doppler reaching this share of the half band = aliased
PEAK_DB_FLOOR = -999.0  # peak amplitude of an all-zero cube
_TINY = float(np.finfo(np.float32).tiny)
_DB = np.float32(10.0 / math.log(10.0))


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

    def as_array(self) -> np.ndarray:
        # the fields' values as they are (`astuple` would deep-copy each float first: ~20 us)
        return np.array([getattr(self, name) for name in FEATURE_NAMES], dtype=np.float32)


FEATURE_NAMES: tuple[str, ...] = tuple(f.name for f in fields(Features))
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
    #: physical estimates only 1:1 verification reads (`signatures.verify`), not classifier
    #: inputs: the bundles' feature vector stays as trained. Empty where not measured.
    physics: Mapping[str, float] = field(default_factory=dict)

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


def extract(recording, expected_range_m: float | None = None, gate_bins: int = GATE_BINS,
            clutter_suppression: bool = True, quick: bool = False, float64: bool = False,
            fft_backend: str | None = None) -> FeatureResult:
    """Features of a `Recording` (see `extract_iq`)."""
    return extract_iq(recording.iq, recording.config, expected_range_m, gate_bins, clutter_suppression,
                      quick=quick, float64=float64, domain=recording.domain, fft_backend=fft_backend)


def extract_iq(iq: np.ndarray, config: RadarConfig, expected_range_m: float | None = None,
               gate_bins: int = GATE_BINS, clutter_suppression: bool = True,
               full_cube: bool = False, quick: bool = False, float64: bool = False,
               domain: str = "if", fft_backend: str | None = None) -> FeatureResult:
    """Features of a bare cube (chirps x samples, any numeric dtype).

    `expected_range_m` (range at the dwell, e.g. from Remote ID) centres the gate
    there and counts only a detection within it; it must lie inside the recorded
    window. `full_cube=True` runs the slow-time work on every range bin first
    (the ungated baseline of the benchmark; same numbers, more work). `quick=True`
    computes only `QUICK_FEATURES` (no flash estimator, cadence or CNN patch: a fast
    configuration of the run-time-versus-error benchmark); the others are 0 and the
    patch is empty. `float64=True` runs every array stage in float64/complex128: the
    reference the float32 default is measured against (`authn bench --stress`).

    `domain` (docs/format.md) says what the cube already is: `range` and `cw` cubes are
    range spectra, so no range FFT runs (clutter suppression still removes the slow-time
    mean of every bin); a `cw` cube's one bin is the gate (no CFAR over range: the Doppler
    bins are the reference cells, `_cw_detection`), takes no `expected_range_m` and gives
    range features of 0 (docs/features.md).

    `fft_backend` ('numpy', 'scipy'; None: the process default, `signatures.fft.backend()`)
    runs every transform, the lazy patch's included, on that backend.
    """
    _fft.resolve(fft_backend)
    if gate_bins < 1:
        raise SignaturesError(f"gate_bins must be >= 1, got {gate_bins}")
    if domain not in DOMAINS:
        raise SignaturesError(f"unknown domain {domain!r} (known: {', '.join(DOMAINS)})")
    if domain == "cw" and expected_range_m is not None:
        raise SignaturesError("a CW recording measures no range: an expected range cannot gate it")
    prep = rd.prepare(iq, float64)
    n_chirps, n_bins = prep.iq.shape
    bin_m = config.range_bin_m(n_bins)
    within = None
    if expected_range_m is not None:
        lo, hi = config.range_window_m
        if not (math.isfinite(expected_range_m) and lo <= expected_range_m < hi):
            raise SignaturesError(f"expected range {expected_range_m:g} m is outside the recorded window "
                                  f"[{lo:g}, {hi:g}) m")
        k = int((expected_range_m - lo) / bin_m)
        within = (max(0, k - gate_bins // 2), min(n_bins, k + gate_bins // 2 + 1))
    if prep.all_zero:
        return _empty(config, n_chirps, n_bins, within)
    spectrum = _range_spectrum(prep.iq, clutter_suppression, domain, fft_backend)
    profile = rd.range_profile(spectrum)
    if domain == "cw":
        gate = (0, 1)
    else:
        looks = max(1, n_chirps - 1) if clutter_suppression else n_chirps
        det = rd.detect(profile, looks, within=within)
        gate = _window(det.peak_bin, gate_bins, n_bins)
    if full_cube:  # what an ungated implementation computes before looking at the target
        rd.rd_map(spectrum, config, fft_backend=fft_backend)
        tf.spectrogram(spectrum, config, *tf.stft_params(config, n_chirps), fft_backend=fft_backend)
    slow = spectrum[:, gate[0]:gate[1]]
    dop = rd.doppler_spectrum(slow, fft_backend=fft_backend)
    power = _power(dop)
    raw_power, stationary = (_unsuppressed(prep.iq, dop, power, gate, domain, fft_backend) if clutter_suppression
                             else (power, 0.0))
    if domain == "cw":
        noise_doppler = max(float(median(power[:, 0])), _TINY)
        det = _cw_detection(power[:, 0], float(profile[0]), noise_doppler)
        return _without_range(_features(prep, config, spectrum, profile, det, gate, slow, power, raw_power,
                                         noise_doppler, clutter_suppression, stationary, quick, fft_backend))
    noise_bin = float(median(profile))  # mean noise power per chirp in one range bin
    noise_doppler = max(noise_bin * n_chirps * float(np.mean(rd.hann(n_chirps) ** 2)), _TINY)
    return _features(prep, config, spectrum, profile, det, gate, slow, power, raw_power,
                     noise_doppler, clutter_suppression, stationary, quick, fft_backend,
                     est.subchirp_window(config, n_bins, domain))


def _range_spectrum(iq: np.ndarray, suppress_clutter: bool, domain: str,
                    fft_backend: str | None = None) -> np.ndarray:
    """The cube as range bins: the range FFT of IF (`rd.range_fft`); a `range` or `cw` cube
    already is one, so only its slow-time mean is removed when clutter is suppressed (what
    `rd.range_fft` removes before its FFT, removed after it: the same, by linearity)."""
    if domain == "if":
        return rd.range_fft(iq, suppress_clutter, fft_backend)
    return iq - iq.mean(axis=0, keepdims=True) if suppress_clutter else iq


def _cw_detection(line_power: np.ndarray, mean_power: float, noise_doppler: float) -> rd.Detection:
    """CW: one channel, so no range cells to run CFAR over. The Doppler bins are the
    reference cells instead: detected when the strongest Doppler line exceeds their median
    by the median-CFAR factor of one look at `rd.CFAR_PFA`. SNR: mean power per pulse over
    the median Doppler bin's noise per pulse (an overestimate of the noise, hence an
    underestimate of the SNR, when micro-Doppler fills most of the band)."""
    n = line_power.size
    factor = rd._cfar_factor(1, n, rd.CFAR_PFA)
    detected = float(line_power.max()) > noise_doppler * factor
    noise_pulse = noise_doppler / (n * float(np.mean(rd.hann(n) ** 2)))
    return rd.Detection(detected, 0, 0.0, rd._db(mean_power / noise_pulse), int(detected))


def _without_range(result: FeatureResult) -> FeatureResult:
    """A CW recording's range features are not measured: 0 by definition (docs/features.md)."""
    feats = replace(result.features, mean_range_m=0.0, std_range_m=0.0, range_m=0.0, range_std_m=0.0)
    return replace(result, features=feats)


def _unsuppressed(iq: np.ndarray, dop: np.ndarray, power: np.ndarray,
                  gate: tuple[int, int], domain: str = "if",
                  fft_backend: str | None = None) -> tuple[np.ndarray, float]:
    """Doppler power of the gate before mean removal, and the stationary excess power.

    The removed mean mu (per range bin) adds mu * FFT(window) to the spectrum: for
    the unit-mean periodic Hann, N*mu at zero Doppler and -N*mu/2 at +-1 bin only.
    The excess is sum over the gate of N^2 (|mu|^2 - median over all range bins of
    |mu|^2): the zero-Doppler line power beyond the window's typical clutter.
    """
    n = iq.shape[0]
    mu = _range_spectrum(iq.mean(axis=0, keepdims=True), False, domain, fft_backend)[0]
    mu2 = mu.real ** 2 + mu.imag ** 2
    excess = float(np.sum(np.maximum(mu2[gate[0]:gate[1]] - median(mu2), 0.0))) * n * n
    mu = mu[gate[0]:gate[1]]
    out = power.copy()
    c = n // 2
    for j, w in ((0, 1.0), (-1, -0.5), (1, -0.5)):
        if 0 <= c + j < n and (j == 0 or n > 2):
            out[c + j] = _power(dop[c + j] + mu * np.float32(n * w))
    return out, excess


def _power(z: np.ndarray) -> np.ndarray:
    return z.real ** 2 + z.imag ** 2


def _window(centre: int, size: int, n: int) -> tuple[int, int]:
    size = min(size, n)
    lo = min(max(0, centre - size // 2), n - size)
    return lo, lo + size


def _features(prep: rd.Prepared, config: RadarConfig, spectrum: np.ndarray, profile: np.ndarray,
              det: rd.Detection, gate: tuple[int, int], slow: np.ndarray, power: np.ndarray,
              raw_power: np.ndarray, noise_doppler: float, suppressed: bool,
              stationary: float, quick: bool = False, fft_backend: str | None = None,
              subchirp: int = 0) -> FeatureResult:
    n_chirps, n_bins = spectrum.shape
    bin_m = config.range_bin_m(n_bins)
    dop_bin_hz = config.prf_hz / n_chirps
    lam = config.doppler_wavelength_m(n_bins)  # Doppler -> velocity at the sweep's mid frequency
    d = power.sum(axis=1)  # Doppler intensity profile over the gate (fftshifted)
    d_raw = raw_power.sum(axis=1)
    centre = n_chirps // 2  # index of zero Doppler after fftshift
    # Hovering when the removed zero-Doppler power beats the strongest remaining line AND
    # no narrow moving line stands out of the micro-Doppler: strong clutter in the target's
    # bin must not hide a moving body. A moving body line (about as strong as all blades
    # together) sits in ~3 Doppler bins while the blades spread over more than half of them,
    # so its peak-to-median exceeds n/6; a hovering airframe's blade comb stays below it.
    contrast = float(d.max()) / max(float(median(d)), _TINY)
    hovering = suppressed and stationary > float(d.max()) and contrast < n_chirps / MOVING_LINE_BINS
    body_idx, vel_std_bins = _body_line(d, d_raw, centre, hovering)
    body_hz = (body_idx - centre) * dop_bin_hz
    velocity = body_hz * lam / 2.0
    vel_std = vel_std_bins * dop_bin_hz * lam / 2.0
    dwell = n_chirps * config.pri_s
    snr = max(10.0 ** (det.snr_db / 10.0), 1e-3)
    range_mid = config.range_offset_m + det.peak_bin_frac * bin_m
    if hovering:
        hover_bin = hover_range_bin(profile[None, :], np.array([det.peak_bin]), np.array([float(median(profile))]))
        range_est = config.range_offset_m + float(hover_bin[0]) * bin_m
    else:
        range_est = range_mid
    range_std = bin_m * (0.05 + 1.0 / math.sqrt(snr))

    # --- Doppler axis relative to the body (circular), in Hz --------------------
    rel_bins = np.mod(np.arange(n_chirps) - body_idx + n_chirps // 2, n_chirps) - n_chirps // 2
    rel_hz = (rel_bins * dop_bin_hz).astype(d.dtype)
    total = max(float(d.sum()), _TINY)
    q_d = d / np.float32(total)
    q_r = power.sum(axis=0) / np.float32(total)
    r_axis = (np.arange(gate[0], gate[1]) - det.peak_bin) * bin_m  # metres from the peak bin
    mu_r_rel = float(np.sum(r_axis * q_r))
    std_r = math.sqrt(max(float(np.sum((r_axis - mu_r_rel) ** 2 * q_r)), 0.0))
    mu_hz = float(np.sum(rel_hz * q_d))
    std_hz = math.sqrt(max(float(np.sum((rel_hz - mu_hz) ** 2 * q_d)), 0.0))
    par_db = _db(float(d.max()) / max(float(d.mean()), _TINY))
    # spectral centroid / bandwidth of the micro-Doppler alone: |offset from the body line| over
    # the bins outside the body's +-BODY_BINS, weighted by their power
    micro = np.abs(rel_bins) > BODY_BINS
    micro_power = max(float(d[micro].sum()), _TINY)
    centroid_hz = float(np.sum(np.abs(rel_hz[micro]) * d[micro])) / micro_power
    bandwidth_hz = math.sqrt(max(float(np.sum((np.abs(rel_hz[micro]) - centroid_hz) ** 2 * d[micro]))
                                 / micro_power, 0.0))
    peak_db = _db(float(power.max())) + 20.0 * math.log10(2.0) * prep.log2_scale
    n_peaks = _count_peaks(np.roll(d, n_chirps // 2 - body_idx), noise_doppler * (gate[1] - gate[0]))
    energy_ratio = float(d[~micro].sum()) / total
    q = power / np.float32(total)
    with np.errstate(divide="ignore", invalid="ignore"):
        plogp = np.where(q > 0, q * np.log(np.maximum(q, np.float32(_TINY))), np.float32(0.0))
    entropy = -float(plogp.sum()) / math.log(max(q.size, 2))

    # --- tip speed, blade flashes, rotors ----------------------------------------
    noise_gate = noise_doppler * (gate[1] - gate[0])
    occupied = _smooth(d, max(1, n_chirps // 256)) > np.float32(noise_gate * 10 ** (OCCUPANCY_DB / 10))
    occupancy = float(occupied.mean())
    tip, tip_std, aliased = _tip_speed(occupied, rel_bins, body_hz, config, dop_bin_hz)
    values = dict(
        mean_range_m=range_mid + mu_r_rel, mean_doppler_mps=velocity + mu_hz * lam / 2.0,
        std_range_m=std_r, std_doppler_mps=std_hz * lam / 2.0, par_db=par_db,
        spectral_centroid_hz=centroid_hz, spectral_bandwidth_hz=bandwidth_hz, peak_amplitude_db=peak_db,
        num_peaks=float(n_peaks), energy_ratio=energy_ratio, entropy=entropy,
        range_m=range_est - velocity * dwell / 2.0, range_std_m=range_std,
        radial_velocity_mps=velocity, radial_velocity_std_mps=vel_std,
        tip_speed_mps=tip, tip_speed_std_mps=tip_std, tip_aliased=float(aliased), doppler_occupancy=occupancy,
        snr_db=max(det.snr_db, -100.0), detected=float(det.detected))
    if quick:
        feats = Features(**{n: values.get(n, 0.0) for n in FEATURE_NAMES})
        return FeatureResult(det.detected, feats, _no_patch, gate)
    if subchirp:  # the peak bin and its neighbours from sub-chirp windows (estimators docstring)
        sub = est.subchirp_bins(prep.iq, det.peak_bin, subchirp)
        series = est.flash_series(sub, config, body_hz, bin_m * n_bins / subchirp, subchirp)
    else:
        centre_cols = slice(max(0, det.peak_bin - 1 - gate[0]), min(gate[1] - gate[0], det.peak_bin + 2 - gate[0]))
        series = est.flash_series(slow[:, centre_cols], config, body_hz, bin_m, n_bins)
    per = est.periodicity(series)
    rotors = est.rotor_count(per)
    flash = per.flash_rate
    rotor = est.Estimate(flash.value / est.BLADES_ASSUMED, flash.std / est.BLADES_ASSUMED)
    blade = est.Estimate(0.0, 0.0)
    if rotor.value > 0 and tip > 0 and not aliased:  # a lower-bound tip gives no length
        length = tip / (2 * math.pi * rotor.value)
        blade = est.Estimate(length, length * math.hypot(tip_std / tip, rotor.std / rotor.value))

    # --- cadence -----------------------------------------------------------------
    win, hop = tf.stft_params(config, n_chirps)
    cad = tf.cadence(tf.spectrogram(slow, config, win, hop, fft_backend=fft_backend), fft_backend)
    cad_peak, cad_ratio = _cadence_features(cad, flash.value)

    feats = Features(
        **values, flash_rate_hz=flash.value, flash_rate_std_hz=flash.std,
        rotor_rate_hz=rotor.value, rotor_rate_std_hz=rotor.std,
        rotor_count=rotors.value, rotor_count_std=rotors.std, blade_length_m=blade.value,
        blade_length_std_m=blade.std, flash_score=per.score, flash_count=float(per.n_events),
        flash_par_db=per.flash_par_db, cadence_peak_hz=cad_peak, cadence_harmonic_ratio=cad_ratio)
    def patch() -> np.ndarray:
        return _patch(spectrum, config, det.peak_bin, body_idx, fft_backend)
    return FeatureResult(det.detected, feats, patch, gate,
                         physics=physics_estimates(per.rotors_seen.value, per.rotors_seen.std))


def physics_estimates(rotors_seen: float, rotors_seen_std: float) -> dict[str, float]:
    """`FeatureResult.physics` from its estimates (one place for the single and batch paths)."""
    return {"rotors_seen": float(rotors_seen), "rotors_seen_std": float(rotors_seen_std)}


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
    centroid = (cols * w).sum(axis=1) / np.maximum(total, _TINY)
    return np.where(total > 0, centroid, peak_bin.astype(np.float64))


def _db(x: float) -> float:
    return 10.0 * math.log10(max(x, 1e-30))


def _body_line(d: np.ndarray, d_raw: np.ndarray, centre: int, hovering: bool) -> tuple[float, float]:
    """Doppler index (fractional) of the body line and its std in bins.

    Moving body: the strongest line of the clutter-suppressed profile. Hovering
    body (`hovering`: the zero-Doppler power removed from the gate beyond the
    window's median clutter exceeds that line): mean removal erased it with the
    clutter, so the peak of the unsuppressed profile within +-BODY_BINS of zero
    Doppler is taken; the same happens when the suppressed line itself lies there.
    """
    k = int(np.argmax(d))
    src = d
    if hovering or abs(k - centre) <= BODY_BINS:
        lo, hi = max(0, centre - BODY_BINS), min(d.size, centre + BODY_BINS + 1)
        k = lo + int(np.argmax(d_raw[lo:hi]))
        src = d_raw
    frac = rd._interp_peak(src, k)
    line_snr = float(src[k]) / max(float(median(src)), _TINY)
    return frac, 0.05 + 1.0 / math.sqrt(max(line_snr, 1.0))


def _smooth(x: np.ndarray, half: int) -> np.ndarray:
    if half < 1:
        return x
    k = np.full(2 * half + 1, 1.0 / (2 * half + 1), dtype=x.dtype)
    return np.convolve(np.concatenate([x[-half:], x, x[:half]]), k, mode="valid").astype(x.dtype, copy=False)


def _count_peaks(d: np.ndarray, noise: float) -> int:
    """Significant peaks of the (body-centred) Doppler profile: local maxima of the profile
    pooled to <= PEAK_PROFILE_BANDS bands, >= PEAK_PROMINENCE_DB above the higher of the
    lowest points between them and the next higher peak (or the ends) on each side, and
    >= PEAK_ABOVE_NOISE_DB above the noise per band."""
    group = max(1, d.size // PEAK_PROFILE_BANDS)
    m = (d.size // group) * group
    pooled = d[:m].reshape(-1, group).sum(axis=1)
    with np.errstate(divide="ignore"):
        y = np.log(np.maximum(pooled, np.float32(_TINY))) * _DB
    floor = _db(noise * group) + PEAK_ABOVE_NOISE_DB
    n = y.size
    rise = np.ones(n, dtype=bool)
    rise[1:] = y[1:] > y[:-1]
    fall = np.ones(n, dtype=bool)
    fall[:-1] = y[:-1] >= y[1:]
    cand = np.flatnonzero((y >= floor) & rise & fall)
    if cand.size == 0:
        return 0
    # prominence, vectorised over candidates (n <= PEAK_PROFILE_BANDS): the base on each side is
    # the lowest point between the candidate and the nearest higher point (or the end)
    idx = np.arange(n)
    yc = y[cand][:, None]
    higher = y[None, :] > yc
    left, right = idx[None, :] < cand[:, None], idx[None, :] > cand[:, None]
    last_left = np.where(higher & left, idx[None, :], -1).max(axis=1)
    first_right = np.where(higher & right, idx[None, :], n).min(axis=1)
    span_l = left & (idx[None, :] > last_left[:, None])
    span_r = right & (idx[None, :] < first_right[:, None])
    base_l = np.where(span_l, y[None, :], np.inf).min(axis=1)
    base_r = np.where(span_r, y[None, :], np.inf).min(axis=1)
    base_l = np.where(span_l.any(axis=1), base_l, y[cand])
    base_r = np.where(span_r.any(axis=1), base_r, y[cand])
    return int(np.count_nonzero(y[cand] - np.maximum(base_l, base_r) >= PEAK_PROMINENCE_DB))


def _tip_speed(occupied: np.ndarray, rel_bins: np.ndarray, body_hz: float, config: RadarConfig,
               dop_bin_hz: float) -> tuple[float, float, bool]:
    """LOS blade-tip speed from the micro-Doppler extent either side of the body line.

    The extent on each side is the farthest occupied Doppler bin from the body line
    (occupied = smoothed profile OCCUPANCY_DB above the noise). Reaching ALIAS_FRACTION
    of the half band means the tips alias: the value is then the lower bound
    lambda/2 * (PRF/2 - |f_body|).
    """
    half = occupied.size // 2
    ext = [int(rel_bins[occupied & (rel_bins > 0)].max(initial=0)),
           int(-rel_bins[occupied & (rel_bins < 0)].min(initial=0))]
    lam2 = config.wavelength_m / 2.0
    if max(ext) >= ALIAS_FRACTION * half:
        return lam2 * max(config.prf_hz / 2.0 - abs(body_hz), 0.0), 0.0, True
    tip_hz = 0.5 * (ext[0] + ext[1]) * dop_bin_hz
    std_hz = math.hypot(0.5 * abs(ext[0] - ext[1]) * dop_bin_hz, dop_bin_hz)
    return lam2 * tip_hz, lam2 * std_hz, False


def _cadence_features(cad: tf.Cadence, flash_hz: float) -> tuple[float, float]:
    """(strongest cadence frequency above FLASH_RATE_MIN_HZ, share of the cadence spectrum
    within one cadence bin of multiples of the flash rate)."""
    spec = cad.spectrum()
    f = cad.cadence_hz
    use = f >= est.FLASH_RATE_MIN_HZ
    if not use.any():
        return 0.0, 0.0
    total = max(float(spec[use].sum()), _TINY)
    peak = float(f[use][int(np.argmax(spec[use]))]) if total > _TINY else 0.0
    if flash_hz <= 0 or f.size < 2:
        return peak, 0.0
    step = float(f[1] - f[0])
    harm = np.abs(f / flash_hz - np.round(f / flash_hz)) * flash_hz <= step
    return peak, float(spec[use & harm].sum()) / total


def _patch(spectrum: np.ndarray, config: RadarConfig, peak_bin: int, body_idx: float,
           fft_backend: str | None = None) -> np.ndarray:
    """CNN input: Doppler x range power of PATCH_SHAPE[1] range bins around the target, in
    PATCH_SHAPE[0] Doppler bands (Welch: Hann frames of PATCH_SHAPE[0] chirps, averaged;
    as informative as pooling a full-resolution spectrum into bands and several times
    cheaper), rolled so the body's band is the middle one; dB below the patch maximum,
    floored at PATCH_FLOOR_DB and mapped to [0, 1]."""
    n_dop, n_rng = PATCH_SHAPE
    n_chirps, n_bins = spectrum.shape
    lo, hi = _window(peak_bin, n_rng, n_bins)
    spec = tf.spectrogram(spectrum[:, lo:hi], config, n_dop, n_dop, per_column=True, fft_backend=fft_backend)
    bands = spec.power.mean(axis=0)  # (n_dop, range)
    body_band = int(round((body_idx - n_chirps // 2) * n_dop / n_chirps))
    bands = np.roll(bands, -body_band, axis=0)
    out = np.zeros(PATCH_SHAPE, dtype=np.float32)
    out[:, :bands.shape[1]] = _to_unit_db(bands)
    return out


def _no_patch() -> np.ndarray:
    return np.zeros(PATCH_SHAPE, np.float32)


def _to_unit_db(p: np.ndarray) -> np.ndarray:
    peak = max(float(p.max()), _TINY)
    with np.errstate(divide="ignore"):
        db = np.log(np.maximum(p / np.float32(peak), np.float32(_TINY))) * _DB
    return ((np.maximum(db, np.float32(PATCH_FLOOR_DB)) - np.float32(PATCH_FLOOR_DB))
            / np.float32(-PATCH_FLOOR_DB)).astype(np.float32)


def _empty(config: RadarConfig, n_chirps: int, n_bins: int, within: tuple[int, int] | None) -> FeatureResult:
    """An all-zero cube: nothing detected, every feature 0 but the peak amplitude floor."""
    values = {name: 0.0 for name in FEATURE_NAMES}
    values["peak_amplitude_db"] = PEAK_DB_FLOOR
    values["snr_db"] = -100.0
    centre = (within[0] + within[1]) // 2 if within else n_bins // 2
    return FeatureResult(False, Features(**values), _no_patch,
                         _window(centre, GATE_BINS, n_bins))


#: What `detections` calls a target: its CFAR cluster's peak this far above the profile's median
DETECTION_MIN_SNR_DB = 10.0


def detections(recording, clutter_suppression: bool = True,
               min_snr_db: float = DETECTION_MIN_SNR_DB) -> list[tuple[float, float]]:
    """The targets of the range profile: (range m, SNR dB over the profile's median) of the peak
    of each CFAR cluster (contiguous bins over threshold) at least `min_snr_db` strong, strongest
    first; a cluster within GATE_BINS of a stronger one is that one's (range sidelobes, blade
    flashes). [] for a CW return (no range) or an all-zero one. What `authn check --rid-capture`
    compares with the claims (non-cooperative targets); the features look at one target only."""
    if recording.domain == "cw":
        return []
    prep = rd.prepare(recording.iq)
    if prep.all_zero:
        return []
    config = recording.config
    n_chirps, n_bins = prep.iq.shape
    profile = rd.range_profile(_range_spectrum(prep.iq, clutter_suppression, recording.domain))
    looks = max(1, n_chirps - 1) if clutter_suppression else n_chirps
    hits, _ = rd.cfar(profile, looks)
    noise = max(float(median(profile)), 1e-30)
    peaks: list[tuple[int, float]] = []
    k = 0
    while k < n_bins:
        end = k
        while end < n_bins and hits[end]:
            end += 1
        if end > k:
            peak = k + int(np.argmax(profile[k:end]))
            snr = 10.0 * math.log10(max(float(profile[peak]) / noise, 1e-30))
            if snr >= min_snr_db:
                peaks.append((peak, snr))
        k = max(end, k + 1)
    kept: list[tuple[int, float]] = []
    for peak, snr in sorted(peaks, key=lambda p: -p[1]):
        if all(abs(peak - other) > GATE_BINS for other, _ in kept):
            kept.append((peak, snr))
    bin_m = config.range_bin_m(n_bins)
    return [(config.range_offset_m + rd._interp_peak(profile, peak) * bin_m, snr) for peak, snr in kept]
