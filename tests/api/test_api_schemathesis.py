"""Schemathesis over every operation of the OpenAPI document: no input, valid or not, gives a server error.

Requests carry a valid API key so that writes reach the handlers; the examples per operation are bounded so
that the run stays well under a minute.
"""

from __future__ import annotations

import shutil
import tempfile
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

MAX_EXAMPLES = 12


_DATA = Path(tempfile.mkdtemp(prefix="softsig-schemathesis-"))
# jobs stay small: one trial per validation (experiments need 18: refused), 3 s of wall time each
_APP = create_app(
    make_settings(_DATA, compute_timeout=20.0, max_job_trials=1, max_job_seconds=3.0, max_queued_jobs=500)
)
schema = schemathesis.openapi.from_dict(_APP.openapi())
schema.app = _APP  # requests go to the app in-process (ASGI); its lifespan starts with the first one


@pytest.fixture(scope="module", autouse=True)
def _stop_the_app() -> Iterator[None]:
    yield
    asgi.shutdown_lifespans()
    shutil.rmtree(_DATA, ignore_errors=True)


@schema.parametrize()
@settings(
    max_examples=MAX_EXAMPLES,
    deadline=None,
    suppress_health_check=list(HealthCheck),
    derandomize=True,
)
def test_no_server_error(case: Any) -> None:
    response = case.call(headers=AUTH)
    case.validate_response(response, checks=[not_a_server_error])
