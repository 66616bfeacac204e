"""Radar signal processing, array-first: range-Doppler, time-frequency, the blade-flash
estimators and the feature vector they fill (`signatures.features` is its public front)."""
