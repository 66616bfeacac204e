"""Feature variants the run-time-against-error grid (`lab.bench.pareto`) retrains a classifier
on: a shorter dwell (the first 1/2, 1/3 or 1/4 of the chirps) and the quick tier.

Each is a named module-level function because the training-set cache key names the featurizer
(`signatures.train.dataset.feature_version`): renaming or moving one regenerates its training set.
"""

from __future__ import annotations

import dataclasses

from signatures.features import extract

#: The dwell fractions the grid tries (1/2, 1/3, 1/4 of the chirps); the benchmark also reports
#: the FFT floor of each.
DWELL_DIVISORS = (2, 3, 4)


def _head(rec, divisor: int):
    """The recording's first 1/divisor of the dwell."""
    return dataclasses.replace(rec, iq=rec.iq[: max(1, rec.iq.shape[0] // divisor)])


def features_half(rec, expected_range_m: float | None = None):
    return extract(_head(rec, 2), expected_range_m)


def features_third(rec, expected_range_m: float | None = None):
    return extract(_head(rec, 3), expected_range_m)


def features_quarter(rec, expected_range_m: float | None = None):
    return extract(_head(rec, 4), expected_range_m)


def features_quarter_quick(rec, expected_range_m: float | None = None):
    return extract(_head(rec, 4), expected_range_m, quick=True)


def features_quick(rec, expected_range_m: float | None = None):
    return extract(rec, expected_range_m, quick=True)
