"""Schemathesis over every operation of the OpenAPI document: the service does what its document says.

Every response is checked by schemathesis' conformance checks: no server error; status codes, media types,
headers and bodies as declared; reads and writes refused without a key exactly where the document declares the
key; a missing required header refused; an undeclared method answered 405 with an ``Allow`` header naming the
documented methods; schema-invalid data refused; schema-valid data accepted. The document is the app's own, shaped
by the test's settings (:mod:`softsig_service.api.contract`).

One check is left out on some operations, each for a reason written beside it in :data:`NOT_STATABLE`: whether
*schema-valid* data is accepted depends there on what JSON Schema cannot state (a file's contents, the registry's
state, relations between fields and with the arm's reach). Those operations still get every other check, and
their refusals are 422 problems naming the field (``tests/api/test_api_door_validation.py``). The stateful
checks (``use_after_free``, ``ensure_resource_availability``) need links between operations and are not run.
A missing ``If-Match`` is 428 Precondition Required (RFC 6585 §3), the status made for it, so 428 is added to the
statuses that check expects.

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
from schemathesis.checks import (
    allow_header_conformance,
    content_type_conformance,
    ignored_auth,
    missing_required_header,
    negative_data_rejection,
    not_a_server_error,
    positive_data_acceptance,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
    unsupported_method,
)
from schemathesis.config import SchemathesisConfig
from schemathesis.python import asgi

from softsig_service.api.app import create_app

MAX_EXAMPLES = 12
CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
    ignored_auth,
    missing_required_header,
    unsupported_method,
    allow_header_conformance,
    negative_data_rejection,
    positive_data_acceptance,
]

_FILES = "its files must be a hand (a manifest naming a model of the description's format, and the model's "
_FILES += "meshes): JSON Schema sees binary"
NOT_STATABLE: dict[str, str] = {
    "POST /v1/hands": _FILES,
    "PUT /v1/hands/{hand}": _FILES,
    "POST /v1/hands/archive": "the archive must be a .zip or .tar.gz of a hand folder: JSON Schema sees binary",
    "POST /v1/hands/{hand}/signatures/markers": "the file must be a marker CSV of the hand's reference points",
    "POST /v1/plans": "the hand must be registered (registry state) and the object rest above the table, within "
    "the arm's reach, a mesh's faces index its vertices (relations between fields and with the arm)",
    "POST /v1/validations": "as a plan: a registered hand, an object resting above the table within reach",
    "POST /v1/experiments": "the hand must be registered (registry state)",
    "POST /v1/hands/{hand}/signatures/stiffness": "the object must be one the hand can grasp: resting on the table, "
    "between its fingers when they close (a relation with the hand's geometry)",
    "POST /v1/objects": "as a plan's object: resting above the table, a mesh's faces indexing its vertices; a file "
    "must be a mesh or cloud of the type its name says (JSON Schema sees binary)",
    "POST /v1/segmentations": "the cloud must hold a horizontal table plane and something standing on it",
    "POST /v1/hands/{hand}/signatures/capture": "the grid's simulations (a product of step, half_width, n_theta "
    "and holdout) are capped, and its object must be graspable by the hand",
    "POST /v1/hands/{hand}/outcomes": "at least one cell or trial, a cell given once, its successes at most its "
    "trials (relations between fields and items)",
    "POST /v1/calibrations": "the hand must declare calibration parameters and hold outcomes (registry state); "
    "the budget must pay for two parameter sets of its cells, within the service's cap (relations with them)",
}
"""Operations where schema-valid data may be refused, and why (every other check runs on them)."""

_DATA = Path(tempfile.mkdtemp(prefix="softsig-schemathesis-"))
# jobs stay small: one trial per experiment cell or 18 per validation, 3 s of wall time each
_APP = create_app(
    make_settings(_DATA, compute_timeout=20.0, max_job_trials=18, max_job_seconds=3.0, max_queued_jobs=500)
)
_CONFIG = SchemathesisConfig.from_dict(
    {"checks": {"missing_required_header": {"expected-statuses": ["400", "401", "403", "406", "415", "422", "428"]}}}
)
schema = schemathesis.openapi.from_dict(_APP.openapi(), config=_CONFIG)
schema.app = _APP  # requests go to the app in-process (ASGI); its lifespan starts with the first one


@pytest.fixture(scope="module", autouse=True)
def _stop_the_app() -> Iterator[None]:
    yield
    asgi.shutdown_lifespans()
    shutil.rmtree(_DATA, ignore_errors=True)


def test_every_exception_names_an_operation_of_the_document() -> None:
    operations = {f"{method.upper()} {path}" for path, item in _APP.openapi()["paths"].items() for method in item}
    assert set(NOT_STATABLE) <= operations, set(NOT_STATABLE) - operations


@schema.parametrize()
@settings(
    max_examples=MAX_EXAMPLES,
    deadline=None,
    suppress_health_check=list(HealthCheck),
    derandomize=True,
)
def test_the_service_does_what_its_document_says(case: Any) -> None:
    checks = CHECKS
    if case.operation.label in NOT_STATABLE:
        checks = [check for check in CHECKS if check is not positive_data_acceptance]
    response = case.call(headers=AUTH)
    case.validate_response(response, checks=checks)
