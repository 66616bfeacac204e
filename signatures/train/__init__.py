"""Making model bundles: data sets, training (scikit-learn, torch), evaluation, site enrolment,
time estimates; never imported by a check."""
