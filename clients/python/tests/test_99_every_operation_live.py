"""The live tests, taken together, called every operation of the client's table against the real
service, and every request they sent fits the OpenAPI documents (the same checks as
test_00_openapi_in_step.py, on what really went over the wire; a request answered with an
error, bad input sent on purpose, is checked for its fields, not its values)."""

from __future__ import annotations

import pytest
from conftest import LIVE_CALLS, Service
from openapi_check import request_problems

from mentalsim_client import OPERATIONS

LIVE_MODULES = {"test_10_knowledge.py", "test_20_plan.py", "test_30_jobs.py", "test_40_errors.py"}


def test_every_operation_was_called_against_the_service(service: Service, kitchen: str, request: pytest.FixtureRequest) -> None:
    collected = {item.path.name for item in request.session.items}
    if not LIVE_MODULES <= collected:
        pytest.skip(f"only with every live module collected ({sorted(LIVE_MODULES - collected)} were not)")
    used = set()
    problems = []
    for call in LIVE_CALLS:
        # Bad input sent on purpose (answered 4xx) has the right fields, not the right values.
        values = 200 <= call.status < 300
        op, p = request_problems(call.method, call.raw_path, call.query, call.headers, call.content_type, call.body, values)
        problems += p
        if op is not None:
            used.add(op.operation_id)
    assert not problems, "\n".join(problems)
    assert used == set(OPERATIONS), f"never called against the service: {sorted(set(OPERATIONS) - used)}"
