"""The radar side: from a recorded return to micro-Doppler evidence and a class.

- Input: `recording` (the file format, docs/format.md), `radar` (waveform configuration and
  presets), `profiles` (airframe profiles).
- Simulation: `scene`, `simulate`, `sampling` (random scenes for training and benchmarks).
- Processing: `fft`, `rd` (range-Doppler), `timefreq` (spectrograms), `stats`,
  `flash_series`, `flash_period`, `flash_spectrum`, `rotor_lines` (blade flashes: flash rate, rotor
  count and rotors seen), `features` (the feature vector), `views` (plots' data).
- Classifiers: `dataset`, `training`, `classifiers`, `openset`, `cnn`,
  `modelcard`, `inference` (the shipped bundles at check time), `evaluate`, `accuracy`.
"""

__all__ = ["features", "inference", "profiles", "radar", "recording", "scene", "simulate"]
