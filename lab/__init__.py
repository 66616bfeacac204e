"""The laboratory, distribution authn-lab (lab/pyproject.toml): benchmarks (`authn bench`), the
held-out test world and the estimator accuracy runs. Above the whole product in the layers: it
imports the radar, registry, decision and CLI packages; nothing in the product imports it. Its
commands reach `authn` through the `authn.plugins` entry points (`lab.cli`)."""
