"""Blade-flash estimators over a batch of returns that share a radar configuration.

The same estimates as `signatures.estimators` (flash series, periodicity, rotor count)
for B gates at once: `flash_series_batch(slow[B, chirps, bins], ...)` then
`periodicity_batch(series)`. Row b equals the single-return functions applied to
`slow[b]` and `body_hz[b]` (to float tolerance; tests/features/test_batch_estimators.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from signatures import estimators as est
from signatures.radar import RadarConfig

__all__ = ["FlashSeriesBatch", "PeriodicityBatch", "flash_series_batch", "periodicity_batch"]


@dataclass(frozen=True)
class FlashSeriesBatch:
    """B flash series of equal length (see `estimators.FlashSeries`)."""

    rows: tuple[est.FlashSeries, ...]


@dataclass(frozen=True)
class PeriodicityBatch:
    """Per row: what `features` takes from `estimators.periodicity` and `estimators.rotor_count`."""

    flash_rate_hz: np.ndarray  # (B,) float64, 0 where no periodicity
    flash_rate_std_hz: np.ndarray
    score: np.ndarray
    n_events: np.ndarray  # (B,) int
    flash_par_db: np.ndarray
    rotor_count: np.ndarray
    rotor_count_std: np.ndarray


def flash_series_batch(slow: np.ndarray, config: RadarConfig, body_hz: np.ndarray,
                       range_bin_m: float, n_fft: int) -> FlashSeriesBatch:
    """`estimators.flash_series` of every row of `slow` (B, chirps, bins) with its `body_hz[b]`."""
    return FlashSeriesBatch(tuple(est.flash_series(slow[b], config, float(body_hz[b]), range_bin_m, n_fft)
                                  for b in range(slow.shape[0])))


def periodicity_batch(series: FlashSeriesBatch) -> PeriodicityBatch:
    """`estimators.periodicity` and `estimators.rotor_count` of every row."""
    pers = [est.periodicity(s) for s in series.rows]
    rotors = [est.rotor_count(p) for p in pers]
    f = np.array
    return PeriodicityBatch(f([p.flash_rate.value for p in pers]), f([p.flash_rate.std for p in pers]),
                            f([p.score for p in pers]), f([p.n_events for p in pers], dtype=int),
                            f([p.flash_par_db for p in pers]), f([r.value for r in rotors]),
                            f([r.std for r in rotors]))
