"""The long schemathesis run (``-m slow``): every operation of the OpenAPI document with a valid API key, at least
5,000 generated cases in all, and no response is a server error. The figures (cases, statuses) are printed at
the end and written to ``<tmp>/softsig-schemathesis-slow.json``.

Run: ``.venv/bin/python -m pytest -m slow tests/api/test_api_schemathesis_slow.py -p no:xdist -s``
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from api_helpers import AUTH, make_settings
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.python import asgi

from softsig_service.api.app import create_app

EXAMPLES_PER_OPERATION = 220
MIN_CASES = 5000

_DATA = Path(tempfile.mkdtemp(prefix="softsig-schemathesis-slow-"))
_APP = create_app(
    make_settings(_DATA, compute_timeout=20.0, max_job_trials=18, max_job_seconds=3.0, max_queued_jobs=5000)
)
schema = schemathesis.openapi.from_dict(_APP.openapi())
schema.app = _APP
_STATUSES: Counter[int] = Counter()
_OPERATIONS: set[str] = set()


@pytest.fixture(scope="module", autouse=True)
def _figures() -> Iterator[None]:
    yield
    asgi.shutdown_lifespans()
    shutil.rmtree(_DATA, ignore_errors=True)
    figures = {"cases": sum(_STATUSES.values()), "operations": len(_OPERATIONS),
               "statuses": dict(sorted(_STATUSES.items()))}  # fmt: skip
    Path(tempfile.gettempdir(), "softsig-schemathesis-slow.json").write_text(json.dumps(figures, indent=2))
    print("\nschemathesis:", json.dumps(figures))
    assert figures["cases"] >= MIN_CASES, figures
    assert not any(status >= 500 for status in _STATUSES), figures


@pytest.mark.slow
@schema.parametrize()
@settings(
    max_examples=EXAMPLES_PER_OPERATION,
    deadline=None,
    suppress_health_check=list(HealthCheck),
    derandomize=True,
)
def test_no_server_error_over_many_cases(case: Any) -> None:
    response = case.call(headers=AUTH)
    _STATUSES[response.status_code] += 1
    _OPERATIONS.add(f"{case.operation.method.upper()} {case.operation.path}")
    case.validate_response(response, checks=[not_a_server_error])
