"""The decision layer: is the drone the radar sees the registered UAV it claims to be?

The decision core, in the order a check runs (docs/architecture.md draws it):

- `check`: the `Checker`, stage by stage; `evidence`: the typed evidence of one check;
  `kinematics`: the declared Remote ID state against the radar's range and velocity;
  `policy`: Cedar evaluation; `audit`: the append-only Merkle-tree log (with `merkle`,
  `logkey`).
- Around it: `errors` (exit codes), `parsing` (dates, validation messages), `scenario` and
  `demo` (simulated flights for the demo and tests), `cli` (the `authn` command), `bench`
  (benchmarks and experiments, never on the check path).

Submodules are imported where used, never here: `authn check` starts fast.
"""

__all__ = ["audit", "check", "errors", "evidence", "kinematics", "logkey", "merkle", "parsing", "policy"]
