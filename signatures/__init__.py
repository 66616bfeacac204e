"""The radar side: from a recorded return to micro-Doppler evidence and a class.

Shared by every sub-package: `errors`, `profiles` (airframe profiles), `radar` (waveform
configuration and presets), `recording` (the file format, docs/format.md). The public fronts:
`features` (the feature vector of returns) and `views` (plots' data). Sub-packages by job, each
importing only those listed before it, the fronts and the shared modules: `dsp` (range-Doppler,
spectrograms, the blade-flash estimators, the feature implementation), `classify` (the shipped
bundles at check time, 1:1 verification), `sim` (the signal model and random scenes), `importers`
(foreign captures as recordings), `train` (data sets, training, evaluation, enrolment). Shipped
data: `data/` (profiles), `models/` (bundles).
"""

__all__ = ["classify", "dsp", "errors", "features", "importers", "profiles", "radar", "recording", "sim", "train",
           "views"]
