"""Property-based fuzz of the HTTP API from its own OpenAPI schema (schemathesis): valid and
invalid requests to every operation, with an admin key; no response may be a server error.

AUTHN_FUZZ_EXAMPLES sets the examples per operation and mode (default sized for CI: with
14 operations, positive and negative, >= 1000 requests in total)."""

from __future__ import annotations

import os
from collections import Counter

import schemathesis
from hypothesis import HealthCheck, given, settings
from hypothesis.errors import Unsatisfiable

EXAMPLES = int(os.environ.get("AUTHN_FUZZ_EXAMPLES", "60"))
MIN_REQUESTS = 1000


def test_no_server_errors_in_generated_requests(server, keys) -> None:
    from schemathesis import GenerationMode

    schema = schemathesis.openapi.from_url(f"{server.url}/openapi.json")
    headers = {"Authorization": f"Bearer {keys.admin}"}
    statuses: Counter[int] = Counter()
    failures: list[str] = []
    operations = [r.ok() for r in schema.get_all_operations()]
    assert len(operations) >= 14

    for op in operations:
        for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE):
            @given(case=op.as_strategy(mode))
            @settings(max_examples=EXAMPLES, deadline=None, database=None, derandomize=True,
                      suppress_health_check=list(HealthCheck))
            def run(case) -> None:
                resp = case.call(base_url=server.url, headers=headers, timeout=30)
                statuses[resp.status_code] += 1
                if resp.status_code >= 500:
                    failures.append(f"{case.method} {case.formatted_path}: {resp.status_code} {resp.text[:200]}")

            try:
                run()
            except Unsatisfiable:  # an operation without inputs has no invalid request to send
                assert mode is GenerationMode.NEGATIVE, op.label
    total = sum(statuses.values())
    print(f"schemathesis: {total} requests, statuses {dict(sorted(statuses.items()))}")
    assert not failures, failures[:5]
    assert total >= MIN_REQUESTS, (total, dict(statuses))
    assert server.proc.poll() is None
