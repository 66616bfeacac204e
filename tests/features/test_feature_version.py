"""The cache key's versions are kept honest: the features (and the simulator) of fixed, seeded
scenes are pinned per version.

Cached training sets are keyed on `signatures.features.FEATURE_VERSION` and
`signatures.sim.simulate.SIMULATOR_VERSION`, not on the source code
(`signatures.train.dataset.feature_version`). A change to the numbers without a version bump would
silently reuse stale cached datasets; these tests fail instead.

Golden values are stored rounded to 4 significant digits and compared with a relative tolerance
of 1e-3 (float32 against the float64 pipeline differs by ~1e-7 on these scenes), so float noise
across machines does not trip them, and a failure names the values that moved. (Values rather
than a digest of the rounded values: a digest flips whenever float noise crosses a rounding
boundary, and says nothing about what changed.)
"""

from __future__ import annotations

import numpy as np

from signatures.features import FEATURE_NAMES, FEATURE_VERSION, extract
from signatures.sim.scene import Nuisance
from signatures.sim.simulate import SIMULATOR_VERSION
from tests.features.conftest import sim

RTOL = 1e-3
ATOL = 1e-6  # for values that are 0

#: Fixed scenes (tests/features/conftest.py `sim`: paper preset unless named, 400 m, 10 dB).
SCENES = {
    "m300_moving": dict(radial_speed_mps=6.0, seed=1),
    "m600_hover": dict(model="m600", radial_speed_mps=0.0, seed=2),
    "bird": dict(kind="bird", model=None, radial_speed_mps=4.0, seed=3),
    "phantom4_wide_hover": dict(model="phantom4", preset="wide", radial_speed_mps=0.0, seed=5),  # from version 3
    "m300_cw_sband_tagged_hover": dict(preset="cw-sband", radial_speed_mps=0.0, tagged_blades=2, seed=6),  # from 5
    # every blade tagged alike: equal blades, read at twice their flash rate before version 7
    "m300_cw_sband_equal_tags_hover": dict(preset="cw-sband", radial_speed_mps=0.0, tagged_blades=8, seed=10),
    # flying: its clutter's line, at minus the body's Doppler, left out of the flash envelope from version 10
    "m300_cw_sband_tagged_moving": dict(preset="cw-sband", radial_speed_mps=6.0, tagged_blades=2, seed=11),
    # accelerating at 0 dB over swaying clutter: read hovering (0 m/s) until version 11 followed its line
    "m300_cw_sband_tagged_accelerating": dict(preset="cw-sband", radial_speed_mps=6.0, tagged_blades=2, seed=13,
                                              snr_db=0.0, clutter_to_signal_db=30.0,
                                              nuisance=Nuisance(radial_accel_mps2=-2.5, clutter_spread_mps=0.3)),
}

#: (FEATURE_VERSION, SIMULATOR_VERSION) -> scene -> `extract(rec).as_array()` (FEATURE_NAMES order).
GOLDEN_FEATURES = {
    ("1", "1"): {
        "m300_moving": (400.4, 5.974, 0.592, 2.971, 24.36, 5244, 3185, 90.45, 9, 0.938, 0.286, 400.1, 0.09587, 6,
                        0.004714, 80.07, 0.1217, 40.03, 0.06086, 6, 1, 16.1, 0, 0, 0, 1, 5.3, 11, 24.71, 0.8517,
                        38.63, 0.9655, 26.76, 1),
        "m600_hover": (400, -0.4907, 0.8142, 11.49, 19.12, 5764, 3277, 72.47, 9, 0.2043, 0.8346, 400, 0.1665,
                       -0.00648, 0.004357, 73.27, 0.1868, 36.64, 0.09338, 6, 0, 22.1, 0, 0, 0, 1, 9, 16, 23.78,
                       0.7167, 38.63, 1, 18.66, 1),
        "bird": (400.1, 3.611, 0.5858, 1.234, 23.93, 1324, 1286, 91.53, 2, 0.8774, 0.3345, 400, 0.09339, 3.857,
                 0.004051, 0, 0, 0, 0, 0, 0, 1.842, 1.476, 0, 0, 0, 0, 1, 27.78, 0.08667, 1506, 0, 27.24, 1),
    },
    ("2", "2"): {
        "m300_moving": (400.3, 5.989, 0.8364, 6.711, 23.19, 5509, 3224, 90.63, 2, 0.7077, 0.508, 400.1, 0.1001, 6.001,
                        0.006323, 79.74, 0.2028, 39.87, 0.1014, 4, 0, 16.1, 0, 0, 0, 1, 5.3, 9, 19.57, 1, 77.25,
                        0.9905, 25.99, 1),
        "m600_hover": (400.2, -0.1511, 1.293, 12.45, 13.67, 5744, 3288, 72.85, 4, 0.06437, 0.9377, 400.1, 0.2348,
                       -0.006639, 0.005186, 73.61, 0.2627, 36.81, 0.1314, 6, 0.5, 22.1, 0, 0, 0, 1, 5, 11, 19.2, 1,
                       309, 1, 14.66, 1),
        "bird": (400.1, 3.61, 0.5861, 1.235, 23.94, 1324, 1284, 91.54, 2, 0.8769, 0.3347, 400, 0.09335, 3.857,
                 0.004051, 0, 0, 0, 0, 0, 0, 2.137, 1.77, 0, 0, 0, 0, 0, 0, 0.09167, 1506, 0, 27.25, 1),
    },
}
# FEATURE_VERSION 3 changed the flash period's half rule, which `paper` (coherent checks) does not use;
# it adds a `wide` scene, so that a change to `wide` alone needs a bump too
GOLDEN_FEATURES[("3", "2")] = {**GOLDEN_FEATURES[("2", "2")],
    "phantom4_wide_hover": (400, -0.1199, 0.7024, 62.91, 20.65, 28130, 16620, 90.07, 1, 0.01989, 0.8636, 400,
                            0.1702, -0.001378, 0.002057, 116.8, 0.0777, 58.42, 0.03885, 4, 0.5, 108.8, 0.03802,
                            0.2963, 0.0002226, 0, 25.1, 22, 17.52, 0.6987, 235.8, 0.5404, 18.39, 1)}
# FEATURE_VERSION 4 widened the flash period search where no coherent checks apply (`wide` only)
GOLDEN_FEATURES[("4", "2")] = {**GOLDEN_FEATURES[("2", "2")],
    "phantom4_wide_hover": (400, -0.1199, 0.7024, 62.91, 20.65, 28130, 16620, 90.07, 1, 0.01989, 0.8636, 400,
                            0.1702, -0.001378, 0.002057, 116.8, 0.07654, 58.4, 0.03827, 4, 0.5, 108.8, 0.03802,
                            0.2964, 0.0002201, 0, 27.3, 22, 17.52, 0.6987, 235.8, 0.5397, 18.39, 1)}

# FEATURE_VERSION 5 follows the waveform on long, low-PRF dwells (envelope-spectrum flash rate, rotors seen,
# a CW body at zero Doppler, wavelength-scaled flash lobe and STFT window): `paper` and `wide` unchanged
GOLDEN_FEATURES[("5", "2")] = {**GOLDEN_FEATURES[("4", "2")],
    "m300_cw_sband_tagged_hover": (0.0, -0.4856, 0.0, 61.36, 14.51, 1218.0, 591.7, 48.99, 14.0, 0.00434, 0.8209,
                                   0.0, 0.0, 0.002663, 0.003178, 80.49, 0.3052, 40.25, 0.1526, 2.0, 0.5, 94.9,
                                   0.7506, 0.3753, 0.003292, 0.0, 4.483, 178.0, 17.72, 0.4351, 80.55, 0.1047, 7.079,
                                   1.0),
}

# FEATURE_VERSION 6 appends the flash envelope's autocorrelation (signatures.dsp.envelope); the other 34 unchanged
GOLDEN_FEATURES[("6", "2")] = {
    "m300_moving": (400.3, 5.989, 0.8364, 6.711, 23.19, 5509.0, 3224.0, 90.63, 2.0, 0.7077, 0.508, 400.1,
        0.1001, 6.001, 0.006323, 79.74, 0.2028, 39.87, 0.1014, 4.0, 0.0, 16.1, 0.0, 0.0, 0.0, 1.0, 5.3, 9.0,
        19.57, 1.0, 77.25, 0.9905, 25.99, 1.0, 0.05764, -0.09469, -0.359, -0.09389, -0.1103, 0.1669, 0.02082,
        -0.03172, -0.03854, 0.01683, 0.01956, 0.0, 0.0, 0.0, 0.0),
    "m600_hover": (400.2, -0.1511, 1.293, 12.45, 13.67, 5744.0, 3288.0, 72.85, 4.0, 0.06437, 0.9377, 400.1,
        0.2348, -0.006639, 0.005186, 73.61, 0.2627, 36.81, 0.1314, 6.0, 0.5, 22.1, 0.0, 0.0, 0.0, 1.0, 5.0,
        11.0, 19.2, 1.0, 309.0, 1.0, 14.66, 1.0, 0.1806, 0.0317, -0.4748, -0.4103, -0.06099, 0.07294, 0.1758,
        0.02119, 0.01428, -0.03309, 0.0141, 0.0, 0.0, 0.0, 0.0),
    "bird": (400.1, 3.61, 0.5861, 1.235, 23.94, 1324.0, 1284.0, 91.54, 2.0, 0.8769, 0.3347, 400.0, 0.09335,
        3.857, 0.004051, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.137, 1.77, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.09167,
        1506.0, 0.0, 27.25, 1.0, 0.7663, 0.3905, -0.02663, -0.3447, -0.5138, -0.4793, -0.3122, -0.1279, 0.01789,
        0.07368, 0.0646, 0.0, 0.0, 0.0, 0.0),
    "phantom4_wide_hover": (400.0, -0.1199, 0.7024, 62.91, 20.65, 28130.0, 16620.0, 90.07, 1.0, 0.01989, 0.8636,
        400.0, 0.1702, -0.001378, 0.002057, 116.8, 0.07654, 58.4, 0.03827, 4.0, 0.5, 108.8, 0.03802, 0.2964,
        0.0002201, 0.0, 27.3, 22.0, 17.52, 0.6987, 235.8, 0.5397, 18.39, 1.0, -0.7533, 0.7902, -0.5535, 0.5308,
        -0.3261, 0.2255, -0.03785, -0.09216, 0.1693, -0.2823, 0.3021, -0.4176, 0.3575, -0.4071, 0.302),
    "m300_cw_sband_tagged_hover": (0.0, -0.4856, 0.0, 61.36, 14.51, 1218.0, 591.7, 48.99, 14.0, 0.00434, 0.8209,
        0.0, 0.0, 0.002663, 0.003178, 80.49, 0.3052, 40.25, 0.1526, 2.0, 0.5, 94.9, 0.7506, 0.3753, 0.003292,
        0.0, 4.483, 178.0, 17.72, 0.4351, 80.55, 0.1047, 7.079, 1.0, 0.05871, -0.2438, -0.3101, -0.2668,
        -0.07878, 0.807, 0.241, -0.23, -0.2923, -0.283, -0.1551, 0.5845, 0.4604, -0.2009, -0.2783),
}

# FEATURE_VERSION 7: a long dwell's flash rate needs a line of its own, and the turn doubling needs the
# approaching-minus-receding envelope to hold the sum's power at the rate (equal blades read at 2x before)
GOLDEN_FEATURES[("7", "2")] = {
    **GOLDEN_FEATURES[("6", "2")],
    "m300_cw_sband_equal_tags_hover": (0.0, 1.695, 0.0, 58.2, 21.19, 1122.0, 628.4, 57.51, 49.0, 0.005992, 0.718,
        0.0, 0.0, -0.003119, 0.003235, 80.28, 0.3052, 40.14, 0.1526, 1.0, 0.0, 99.22, 0.1493, 0.3934, 0.001608,
        0.0, 4.417, 254.0, 13.93, 0.4485, 80.55, 0.1369, 9.53, 1.0, 0.265, -0.3408, -0.4975, -0.432, 0.1424,
        0.801, 0.3702, -0.2189, -0.4967, -0.4913, 0.006283, 0.5493, 0.5119, -0.05605, -0.4828),
}

# FEATURE_VERSION 8: a long dwell's ends are tapered before its Doppler spectrum (moving clutter's
# sidelobes no longer cross the band); paper and wide features unchanged
GOLDEN_FEATURES[("8", "2")] = {
    **GOLDEN_FEATURES[("7", "2")],
    "m300_cw_sband_tagged_hover": (0.0, -0.4856, 0.0, 61.36, 14.51, 1218.0, 591.7, 48.99, 14.0, 0.00434, 0.8209,
        0.0, 0.0, 0.002663, 0.003178, 80.46, 0.3052, 40.23, 0.1526, 2.0, 0.5, 94.9, 0.7506, 0.3754, 0.003293,
        0.0, 4.405, 178.0, 17.72, 0.4351, 80.55, 0.1047, 7.079, 1.0, 0.05871, -0.2438, -0.3101, -0.2668,
        -0.07878, 0.807, 0.241, -0.23, -0.2923, -0.283, -0.1551, 0.5845, 0.4604, -0.2009, -0.2783),
    "m300_cw_sband_equal_tags_hover": (0.0, 1.695, 0.0, 58.2, 21.19, 1122.0, 628.4, 57.51, 49.0, 0.005992, 0.718,
        0.0, 0.0, -0.003119, 0.003235, 80.28, 0.3052, 40.14, 0.1526, 1.0, 0.0, 99.22, 0.1493, 0.3934, 0.001609,
        0.0, 4.435, 254.0, 13.93, 0.4485, 80.55, 0.1369, 9.53, 1.0, 0.265, -0.3408, -0.4975, -0.432, 0.1424,
        0.801, 0.3702, -0.2189, -0.4967, -0.4913, 0.006283, 0.5493, 0.5119, -0.05605, -0.4828),
}

# FEATURE_VERSION 9: the flash series also high-passes the radar's frame (`estimators.clutter_pass`: swaying
# clutter no longer buries a moving target's flashes); hovering and CW targets unchanged
GOLDEN_FEATURES[("9", "2")] = {
    **GOLDEN_FEATURES[("8", "2")],
    'm300_moving': (400.3, 5.989, 0.8364, 6.711, 23.19, 5509.0, 3224.0, 90.63, 2.0, 0.7077, 0.508, 400.1, 0.1001, 6.001,
        0.006323, 79.74, 0.2028, 39.87, 0.1014, 5.0, 0.5, 16.1, 0.0, 0.0, 0.0, 1.0, 5.3, 10.0, 19.57, 1.0, 77.25,
        0.9905, 25.99, 1.0, 0.05764, -0.09469, -0.359, -0.09389, -0.1103, 0.1669, 0.02082, -0.03172, -0.03854,
        0.01683, 0.01956, 0.0, 0.0, 0.0, 0.0),
    'bird': (400.1, 3.61, 0.5861, 1.235, 23.94, 1324.0, 1284.0, 91.54, 2.0, 0.8769, 0.3347, 400.0, 0.09335, 3.857,
        0.004051, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.137, 1.77, 0.0, 0.0, 0.0, 0.0, 1.0, 27.78, 0.09167, 1506.0, 0.0,
        27.25, 1.0, 0.7663, 0.3905, -0.02663, -0.3447, -0.5138, -0.4793, -0.3122, -0.1279, 0.01789, 0.07368, 0.0646,
        0.0, 0.0, 0.0, 0.0),
}
GOLDEN_FEATURES[("10", "2")] = {
    **GOLDEN_FEATURES[("9", "2")],
    "m300_cw_sband_tagged_moving": (
        0.0, 5.82, 0.0, 30.49, 32.86, 1133.0, 652.5, 71.18, 8.0, 0.7364, 0.3704, 0.0, 0.0, 5.998, 0.003134, 79.84,
        0.3052, 39.92, 0.1526, 1.0, 0.0, 91.16, 0.8336, 0.3634, 0.003602, 0.0, 3.754, 189.0, 16.52, 0.2866, 39.65,
        0.09494, 10.84, 1.0, 0.2181, -0.2941, -0.4836, -0.3869, 0.1156, 0.7023, 0.3348, -0.157, -0.4571, -0.4158,
        -0.01781, 0.4514, 0.4976, 0.005378, -0.4135),
}

# FEATURE_VERSION 11: an accelerating CW body's line is followed over sub-dwells (extraction._drifting_line);
# every earlier scene unchanged
GOLDEN_FEATURES[("11", "2")] = {
    **GOLDEN_FEATURES[("10", "2")],
    "m300_cw_sband_tagged_accelerating": (
        0.0, -0.02395, 0.0, 3.699, 27.59, 114.3, 75.97, 91.23, 2.0, 0.001026, 0.3467, 0.0, 0.0, 4.99, 0.006013,
        80.04, 0.3052, 40.02, 0.1526, 1.0, 0.0, 4.242, 2.801, 0.01687, 0.01114, 0.0, 0.8123, 102.0, 23.65, 0.03101,
        34.7, 0.03281, 27.32, 1.0, 0.97, 0.9134, 0.8363, 0.7503, 0.6603, 0.5704, 0.4837, 0.402, 0.3277, 0.2583,
        0.1964, 0.1402, 0.08995, 0.04346, 0.002309),
}

# FEATURE_VERSION 12: a long dwell's tip speed is read to within one of its rotor's Doppler lines
# (tip_speed_std_mps and blade_length_std_m grow), and its flash rate keeps to the train where a tag
# pattern or interfering rotors once slipped it (issue 54); paper and wide features unchanged
GOLDEN_FEATURES[("12", "2")] = {
    **GOLDEN_FEATURES[("11", "2")],
    "m300_cw_sband_tagged_hover": (
        0.0, -0.4856, 0.0, 61.36, 14.51, 1218.0, 591.7, 48.99, 14.0, 0.00434, 0.8209, 0.0, 0.0, 0.002663, 0.003178,
        80.46, 0.3052, 40.23, 0.1526, 2.0, 0.5, 94.9, 1.976, 0.3754, 0.007944, 0.0, 4.405, 178.0, 17.72, 0.4351,
        80.55, 0.1047, 7.079, 1.0, 0.05871, -0.2438, -0.3101, -0.2668, -0.07878, 0.807, 0.241, -0.23, -0.2923,
        -0.283, -0.1551, 0.5845, 0.4604, -0.2009, -0.2783),
    "m300_cw_sband_equal_tags_hover": (
        0.0, 1.695, 0.0, 58.2, 21.19, 1122.0, 628.4, 57.51, 49.0, 0.005992, 0.718, 0.0, 0.0, -0.003119, 0.003235,
        80.28, 0.3052, 40.14, 0.1526, 1.0, 0.0, 99.22, 1.829, 0.3934, 0.007406, 0.0, 4.435, 254.0, 13.93, 0.4485,
        80.55, 0.1369, 9.53, 1.0, 0.265, -0.3408, -0.4975, -0.432, 0.1424, 0.801, 0.3702, -0.2189, -0.4967, -0.4913,
        0.006283, 0.5493, 0.5119, -0.05605, -0.4828),
    "m300_cw_sband_tagged_moving": (
        0.0, 5.82, 0.0, 30.49, 32.86, 1133.0, 652.5, 71.18, 8.0, 0.7364, 0.3704, 0.0, 0.0, 5.998, 0.003134, 79.84,
        0.3052, 39.92, 0.1526, 1.0, 0.0, 91.16, 1.996, 0.3634, 0.008077, 0.0, 3.754, 189.0, 16.52, 0.2866, 39.65,
        0.09494, 10.84, 1.0, 0.2181, -0.2941, -0.4836, -0.3869, 0.1156, 0.7023, 0.3348, -0.157, -0.4571, -0.4158,
        -0.01781, 0.4514, 0.4976, 0.005378, -0.4135),
    "m300_cw_sband_tagged_accelerating": (
        0.0, -0.02395, 0.0, 3.699, 27.59, 114.3, 75.97, 91.23, 2.0, 0.001026, 0.3467, 0.0, 0.0, 4.99, 0.006013,
        80.04, 0.3052, 40.02, 0.1526, 1.0, 0.0, 4.242, 3.339, 0.01687, 0.01328, 0.0, 0.8123, 102.0, 23.65, 0.03101,
        34.7, 0.03281, 27.32, 1.0, 0.97, 0.9134, 0.8363, 0.7503, 0.6603, 0.5704, 0.4837, 0.402, 0.3277, 0.2583,
        0.1964, 0.1402, 0.08995, 0.04346, 0.002309),
}

# FEATURE_VERSION 13: a long dwell's flash-rate candidates count a harmonic up to ten times their own
# line, and lines are compared in power, not whitened (a quarter-spaced quad read at half or 2.5x
# its rate); flash_score moves on the CW scenes, paper and wide features unchanged
GOLDEN_FEATURES[("13", "2")] = {
    **GOLDEN_FEATURES[("12", "2")],
    'm300_cw_sband_tagged_hover': (
        0.0, -0.4856, 0.0, 61.36, 14.51, 1218.0, 591.7, 48.99, 14.0, 0.00434, 0.8209, 0.0, 0.0, 0.002663, 0.003178,
        80.46, 0.3052, 40.23, 0.1526, 2.0, 0.5, 94.9, 1.976, 0.3754, 0.007944, 0.0, 4.634, 178.0, 17.72, 0.4351, 80.55,
        0.1047, 7.079, 1.0, 0.05871, -0.2438, -0.3101, -0.2668, -0.07878, 0.807, 0.241, -0.23, -0.2923, -0.283, -0.1551,
        0.5845, 0.4604, -0.2009, -0.2783
    ),
    'm300_cw_sband_equal_tags_hover': (
        0.0, 1.695, 0.0, 58.2, 21.19, 1122.0, 628.4, 57.51, 49.0, 0.005992, 0.718, 0.0, 0.0, -0.003119, 0.003235, 80.28,
        0.3052, 40.14, 0.1526, 1.0, 0.0, 99.22, 1.829, 0.3934, 0.007406, 0.0, 4.489, 254.0, 13.93, 0.4485, 80.55,
        0.1369, 9.53, 1.0, 0.265, -0.3408, -0.4975, -0.432, 0.1424, 0.801, 0.3702, -0.2189, -0.4967, -0.4913, 0.006283,
        0.5493, 0.5119, -0.05605, -0.4828
    ),
    'm300_cw_sband_tagged_moving': (
        0.0, 5.82, 0.0, 30.49, 32.86, 1133.0, 652.5, 71.18, 8.0, 0.7364, 0.3704, 0.0, 0.0, 5.998, 0.003134, 79.84,
        0.3052, 39.92, 0.1526, 1.0, 0.0, 91.16, 1.996, 0.3634, 0.008077, 0.0, 3.77, 189.0, 16.52, 0.2866, 39.65,
        0.09494, 10.84, 1.0, 0.2181, -0.2941, -0.4836, -0.3869, 0.1156, 0.7023, 0.3348, -0.157, -0.4571, -0.4158,
        -0.01781, 0.4514, 0.4976, 0.005378, -0.4135
    ),
    'm300_cw_sband_tagged_accelerating': (
        0.0, -0.02395, 0.0, 3.699, 27.59, 114.3, 75.97, 91.23, 2.0, 0.001026, 0.3467, 0.0, 0.0, 4.99, 0.006013, 80.04,
        0.3052, 40.02, 0.1526, 1.0, 0.0, 4.242, 3.339, 0.01687, 0.01328, 0.0, 0.8186, 102.0, 23.65, 0.03101, 34.7,
        0.03281, 27.32, 1.0, 0.97, 0.9134, 0.8363, 0.7503, 0.6603, 0.5704, 0.4837, 0.402, 0.3277, 0.2583, 0.1964,
        0.1402, 0.08995, 0.04346, 0.002309
    ),
}

# FEATURE_VERSION 14: a long dwell's flash score is also read with the turn's lines in the approaching-minus-
# receding envelope added (flash_spectrum._turn_score), the larger of the two kept; flash_score moves on
# the CW scenes whose blades are tagged, paper and wide features unchanged
GOLDEN_FEATURES[("14", "2")] = {
    **GOLDEN_FEATURES[("13", "2")],
    'm300_cw_sband_tagged_moving': (
        0.0, 5.82, 0.0, 30.49, 32.86, 1133.0, 652.5, 71.18, 8.0, 0.7364, 0.3704, 0.0, 0.0, 5.998, 0.003134, 79.84,
        0.3052, 39.92, 0.1526, 1.0, 0.0, 91.16, 1.996, 0.3634, 0.008077, 0.0, 3.969, 189.0, 16.52, 0.2866, 39.65,
        0.09494, 10.84, 1.0, 0.2181, -0.2941, -0.4836, -0.3869, 0.1156, 0.7023, 0.3348, -0.157, -0.4571, -0.4158,
        -0.01781, 0.4514, 0.4976, 0.005378, -0.4135
    ),
    'm300_cw_sband_tagged_accelerating': (
        0.0, -0.02395, 0.0, 3.699, 27.59, 114.3, 75.97, 91.23, 2.0, 0.001026, 0.3467, 0.0, 0.0, 4.99, 0.006013, 80.04,
        0.3052, 40.02, 0.1526, 1.0, 0.0, 4.242, 3.339, 0.01687, 0.01328, 0.0, 1.368, 102.0, 23.65, 0.03101, 34.7,
        0.03281, 27.32, 1.0, 0.97, 0.9134, 0.8363, 0.7503, 0.6603, 0.5704, 0.4837, 0.402, 0.3277, 0.2583, 0.1964,
        0.1402, 0.08995, 0.04346, 0.002309
    ),
}

SIMULATOR_SUMMARY = ("power of chirps 0-99", "100-199", "200-299", "300-399", "400-499", "500-599",
                     "|lag-1 slow-time autocorrelation|", "its phase (rad)", "peak range bin", "peak range power")

#: SIMULATOR_VERSION -> noise ("noiseless" / "10 dB") -> `_simulator_summary` (SIMULATOR_SUMMARY order).
GOLDEN_SIMULATOR = {
    "1": {
        "noiseless": (1.563, 0.9636, 0.8421, 0.7665, 0.6959, 1.169, 0.8213, 0.8531, 40, 5504),
        "10 dB": (1.674, 1.054, 0.9349, 0.8715, 0.8026, 1.265, 0.8212, 0.8513, 40, 5516),
    },
    "2": {
        "noiseless": (1.284, 1.184, 0.9454, 1.053, 0.7833, 0.7506, 0.8173, 0.853, 40, 4635),
        "10 dB": (1.395, 1.272, 1.041, 1.16, 0.8911, 0.8439, 0.8161, 0.8522, 40, 4643),
    },
}


def _round4(values) -> tuple[float, ...]:
    return tuple(float(f"{float(v):.4g}") for v in values)


def _moved(names, got, want) -> list[str]:
    got, want = np.asarray(got, dtype=np.float64), np.asarray(want, dtype=np.float64)
    bad = ~np.isclose(got, want, rtol=RTOL, atol=ATOL)
    return [f"{n}: {w:.4g} -> {g:.4g}" for n, g, w, b in zip(names, got, want, bad) if b]


def _simulator_summary(snr_db: float | None) -> tuple[float, ...]:
    rec, _ = sim(radial_speed_mps=6.0, snr_db=snr_db, seed=1)
    iq = rec.iq.astype(np.complex128)
    blocks = np.mean(np.abs(iq.reshape(6, -1)) ** 2, axis=1)
    r1 = np.mean(iq[1:] * np.conj(iq[:-1]))
    profile = np.mean(np.abs(np.fft.fft(iq, axis=1)) ** 2, axis=0)
    return (*blocks, abs(r1), np.angle(r1), int(np.argmax(profile)), profile.max())


def test_simulator_matches_its_version() -> None:
    got = {"noiseless": _simulator_summary(None), "10 dB": _simulator_summary(10.0)}
    golden = GOLDEN_SIMULATOR.get(SIMULATOR_VERSION)
    new = "{\n" + "".join(f"    {k!r}: {_round4(v)},\n" for k, v in got.items()) + "}"
    assert golden is not None, (f"no golden simulator summary for SIMULATOR_VERSION={SIMULATOR_VERSION!r}: add "
                                f"GOLDEN_SIMULATOR[{SIMULATOR_VERSION!r}] = {new}")
    moved = {k: m for k in golden if (m := _moved(SIMULATOR_SUMMARY, got[k], golden[k]))}
    assert not moved, (
        f"the simulator's returns of a fixed, seeded scene changed without a version bump: {moved}. "
        "Bump SIMULATOR_VERSION in signatures/sim/simulate.py (cached training sets are keyed on it) and add "
        f"GOLDEN_SIMULATOR[<new version>] = {new} here (and the GOLDEN_FEATURES entry the feature test asks for).")


def test_features_match_their_version() -> None:
    got = {name: extract(sim(**kw)[0]).as_array() for name, kw in SCENES.items()}
    key = (FEATURE_VERSION, SIMULATOR_VERSION)
    new = "{\n" + "".join(f"    {k!r}: {_round4(v)},\n" for k, v in got.items()) + "}"
    golden = GOLDEN_FEATURES.get(key)
    assert golden is not None, f"no golden features for (FEATURE_VERSION, SIMULATOR_VERSION)={key}: add " \
                               f"GOLDEN_FEATURES[{key}] = {new}"
    moved = {k: m for k in golden if (m := _moved(FEATURE_NAMES, got[k], golden[k]))}
    assert not moved, (
        f"the features of fixed, seeded scenes changed without a version bump: {moved}. Bump FEATURE_VERSION "
        "in signatures/features.py (or SIMULATOR_VERSION, if test_simulator_matches_its_version fails too): "
        f"cached training sets are keyed on them. Then add GOLDEN_FEATURES[<new versions>] = {new} here.")
