"""The laboratory's commands, plugged into `authn` by the `authn.plugins` entry points of
lab/pyproject.toml: `bench` (lab/cli/bench.py) and `features accuracy|score`
(lab/cli/features.py). The product never imports them: its CLI loads them by name."""
