"""Features of radar returns: the public front of the feature vector and its extraction.

`extract(recording)` gives one return's `FeatureResult`; `extract_many(recordings)` gives many
at once, batched. Both run the one array-first implementation (`signatures.dsp.extraction`); the
vector's fields and constants live in `signatures.dsp.feature_vector`. Exact definitions:
docs/features.md.
"""

from __future__ import annotations

from signatures.dsp.extraction import (DEFAULT_FFT_BACKEND, MAX_BATCH, batch_size, detections, extract, extract_batch,
                                       extract_iq, extract_many)
from signatures.dsp.feature_vector import (FEATURE_NAMES, FEATURE_VERSION, GATE_BINS, PATCH_SHAPE, QUICK_FEATURES,
                                           FeatureResult, Features, physics_estimates)

__all__ = ["DEFAULT_FFT_BACKEND", "FEATURE_NAMES", "FEATURE_VERSION", "GATE_BINS", "MAX_BATCH", "PATCH_SHAPE",
           "QUICK_FEATURES", "FeatureResult", "Features", "batch_size", "detections", "extract", "extract_batch",
           "extract_iq", "extract_many", "physics_estimates"]
