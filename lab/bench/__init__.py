"""Benchmarks and experiments: `authn bench` and nothing else.

None of this decides anything. The decision core is `authn.check` with `authn.evidence`,
`authn.kinematics`, `authn.policy` and `authn.audit`; this package only drives it on
simulated claims and measures it:

* `decisions`: end-to-end accuracy per claim category (genuine, type / position spoofs,
  unregistered, revoked) and check latency (cold process, batch mode);
* `perf`: where the time goes (per-stage medians, imports, the FFT floor, throughput);
* `pareto`: run time against error over pipeline configurations, and the Pareto front;
* `variants`: the feature variants (shorter dwell, quick tier) the front retrains on;
* `stress`: the numerical stress suite (hostile but legal inputs, and illegal ones).

Submodules are imported on demand (`from lab.bench import pareto`): importing the package
loads nothing heavy.
"""

__all__ = ["decisions", "pareto", "perf", "stress", "variants"]
