"""Running the shipped model bundles on a return's features at check time: numpy members, the
soft vote, open set, calibration, carriers, model cards, and 1:1 verification of a claim."""
