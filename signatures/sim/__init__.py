"""The signal model: simulated scenes, their dechirped IF cubes, random scenes, other radar domains."""
