"""Prometheus metrics of one worker, in a registry of the app's own (no module globals):
checks by decision and reason, per-stage latency from `Outcome.timings_ms`, errors."""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Counter, Histogram, generate_latest

STAGE_BUCKETS = (0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5)


class Metrics:
    def __init__(self) -> None:
        self.registry = CollectorRegistry()
        self.checks = Counter("authn_checks_total", "Checks decided, by decision", ["decision"],
                              registry=self.registry)
        self.reasons = Counter("authn_check_reasons_total", "Reasons given by decided checks",
                               ["decision", "reason"], registry=self.registry)
        self.stages = Histogram("authn_check_stage_seconds", "Time per check stage", ["stage"],
                                buckets=STAGE_BUCKETS, registry=self.registry)
        self.errors = Counter("authn_errors_total", "Requests that ended in an error, by status and kind",
                              ["status", "kind"], registry=self.registry)

    def outcome(self, decision: str, reasons: list[str], timings_ms: dict[str, float]) -> None:
        self.checks.labels(decision).inc()
        for r in reasons:
            self.reasons.labels(decision, r).inc()
        for stage, ms in timings_ms.items():
            self.stages.labels(stage).observe(ms / 1e3)

    def error(self, status: int, kind: str) -> None:
        self.errors.labels(str(status), kind).inc()

    def render(self) -> bytes:
        return generate_latest(self.registry)
