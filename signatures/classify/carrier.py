"""One bundle for a band of carriers: which bundle serves a carrier near its own, and how the
features are put on the bundle's carrier before its classifier sees them (docs/waveform.md
"Carrier band").

A radar that steps its carrier (3.30, 3.35, 3.40 GHz) records the same scene with Doppler
frequencies f_D = 2 v / lambda that differ by the carrier ratio, and nothing else in its waveform
changes. So a bundle serves a recording whose waveform is its own but for the carrier, within
`CARRIER_BAND_REL`, and the features whose value is a Doppler frequency are rescaled by
lambda_recording / lambda_bundle ("as the bundle's carrier would have measured them"). What is
left (features counted in Doppler bins, a spectrum diluted by noise) moves by about the relative
carrier change; `CARRIER_BAND_REL` bounds it.

Pure numpy and closed-form physics; not imported by the feature extractor or the simulator, so it
is no part of a dataset's cache key.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from signatures.radar import SERVES, WAVEFORM_FIELDS, WAVEFORM_REL_TOL, C, Preset, RadarConfig

__all__ = ["ALIAS_BOUND", "CARRIER_BAND_REL", "WAVELENGTH_SCALED", "band_waveform", "carrier_band_hz",
           "carrier_ratio", "normalise"]

#: A bundle serves a recording whose carrier is within this fraction of its own (the rest of the
#: waveform equal): +-2.5 %, so one bundle at 3.35 GHz covers 3.266-3.434 GHz, a radar hopping
#: over 3.30-3.40 GHz (+-1.5 %) with room. Chosen from the physics, not fitted: what rescaling
#: does not undo moves by about the relative carrier change (Doppler extents counted in bins,
#: the Hz moments of a spectrum that noise or aliased flashes fill, the 32-band CNN patch), and
#: 2.5 % of a spread of up to half the band (16 of the patch's 32 bands) is under half a band:
#: below one bin of the patch and below the scene-to-scene spread of every feature (measured at
#: +-1.5 % in docs/waveform.md). 77 GHz +-2.5 % is 75.1-78.9 GHz.
CARRIER_BAND_REL = 0.025

#: Features whose value is a Doppler frequency (Hz): proportional to 1/lambda for the same
#: motion, so multiplied by lambda_recording / lambda_bundle. Velocities in m/s are already
#: wavelength-free (the extractor converts with the recording's own lambda), and the rotation
#: rates (flash_rate_hz, rotor_rate_hz, cadence_peak_hz and their std) are not Doppler frequencies.
WAVELENGTH_SCALED = ("spectral_centroid_hz", "spectral_bandwidth_hz")

#: (feature, flag): where the flag is set the tips alias and the feature is the waveform's bound
#: lambda/2 (PRF/2 - |f_body|) = lambda PRF/4 - |v_body|, not the target's tip speed. The bound
#: moves with the unambiguous velocity lambda PRF/4, so the bundle's carrier reads it
#: (lambda_bundle - lambda_recording) PRF/4 higher.
ALIAS_BOUND = ("tip_speed_mps", "tip_aliased")


def carrier_band_hz(wf: Preset) -> tuple[float, float]:
    """The carriers a bundle of waveform `wf` serves: its own +-CARRIER_BAND_REL."""
    f = wf.config.carrier_hz
    return f * (1.0 - CARRIER_BAND_REL), f * (1.0 + CARRIER_BAND_REL)


def carrier_ratio(bundle: Preset, wf: Preset) -> float | None:
    """f_recording / f_bundle when a bundle of waveform `bundle` serves a recording of `wf`:
    same cube size, a domain it serves, every other WAVEFORM_FIELDS within WAVEFORM_REL_TOL and
    the carrier within CARRIER_BAND_REL; None when it does not serve it. 1.0 is the exact match
    that lookup prefers."""
    if (bundle.n_chirps, bundle.n_samples) != (wf.n_chirps, wf.n_samples) or wf.domain not in SERVES[bundle.domain]:
        return None
    if not all(math.isclose(getattr(wf.config, f), getattr(bundle.config, f), rel_tol=WAVEFORM_REL_TOL)
               for f in WAVEFORM_FIELDS if f != "carrier_hz"):
        return None
    ratio = wf.config.carrier_hz / bundle.config.carrier_hz
    return ratio if abs(ratio - 1.0) <= CARRIER_BAND_REL * (1.0 + 1e-9) else None


def normalise(X: np.ndarray, names: Sequence[str], bundle: RadarConfig, n_samples: int,
              carrier_hz: float | np.ndarray) -> np.ndarray:
    """The feature rows X (B x names), measured at `carrier_hz` (one per row or one for all), as
    a radar of the bundle's waveform would have measured them: WAVELENGTH_SCALED x
    lambda_D,rec / lambda_D,bundle (the Doppler wavelengths the extractor converts with, the
    sweep's mid frequency for FMCW) and ALIAS_BOUND's shift where tips alias. A copy; X itself
    when every carrier is the bundle's (within 1e-9) or no named feature is in `names`."""
    f_rec = np.broadcast_to(np.asarray(carrier_hz, dtype=np.float64), (len(X),))
    if np.all(np.abs(f_rec / bundle.carrier_hz - 1.0) <= 1e-9):
        return X
    cols = list(names)
    scaled = [cols.index(n) for n in WAVELENGTH_SCALED if n in cols]
    tip = cols.index(ALIAS_BOUND[0]) if ALIAS_BOUND[0] in cols and ALIAS_BOUND[1] in cols else -1
    if not scaled and tip < 0:
        return X
    offset = bundle.slope_hz_per_s * (n_samples - 1) / (2.0 * bundle.sample_rate_hz)  # mid-sweep: same for both
    lam_ratio = (bundle.carrier_hz + offset) / (f_rec + offset)  # lambda_D,rec / lambda_D,bundle
    out = np.array(X, dtype=np.float32, copy=True)
    if scaled:
        out[:, scaled] = (out[:, scaled] * lam_ratio[:, None]).astype(np.float32)
    if tip >= 0:
        aliased = out[:, cols.index(ALIAS_BOUND[1])] > 0.5
        shift = (C / bundle.carrier_hz - C / f_rec) * bundle.prf_hz / 4.0
        out[:, tip] = np.where(aliased, out[:, tip] + shift, out[:, tip]).astype(np.float32)
    return out


def band_waveform(waveforms: Sequence[Preset]) -> Preset | None:
    """The one waveform a carrier-stepped radar's recordings enrol as: theirs at the middle of
    their carriers ((lowest + highest) / 2), when every one of them is served by it (the rest of
    the waveform equal within WAVEFORM_REL_TOL, the carrier within CARRIER_BAND_REL: the band a
    check is served in, so every enrolled carrier is one the bundle serves); None otherwise."""
    from signatures.radar import waveform_of

    if not waveforms:
        return None
    first = waveforms[0]
    wf = first
    if len({w.key for w in waveforms}) > 1:
        carriers = [w.config.carrier_hz for w in waveforms]
        mid = (min(carriers) + max(carriers)) / 2.0
        wf = waveform_of(first.config.replace(carrier_hz=mid), first.n_chirps, first.n_samples, first.domain,
                         first.max_range_m)
    return wf if all(carrier_ratio(wf, w) is not None for w in waveforms) else None
