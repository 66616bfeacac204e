"""The radar side: from a recorded return to micro-Doppler evidence and a class.

- Input: `recording` (the file format, docs/format.md), `radar` (waveform configuration and
  presets), `profiles` (airframe profiles).
- Simulation: `scene`, `simulate`, `sampling` (random scenes for training and benchmarks).
- Processing: `fft`, `rd` (range-Doppler), `timefreq` (spectrograms), `stats`,
  `estimators` (blade-flash rate and the other physical estimates), `features` (the feature
  vector), `views` (plots' data).
- Classifiers: `dataset`, `training`, `classifiers`, `openset`, `cnn`,
  `modelcard`, `inference` (the shipped bundles at check time), `evaluate`, `accuracy`.
"""

__all__ = ["features", "inference", "profiles", "radar", "recording", "scene", "simulate"]
