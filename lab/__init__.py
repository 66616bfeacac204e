"""The laboratory: benchmarks (`authn bench`), the held-out test world and the estimator
accuracy runs. Above the product in the layers: it imports the radar, registry and
decision packages; nothing in the product imports it (only the CLI's bench and
`features accuracy` commands, on demand). Its heavier dependencies come with the
`bench` extra."""
