"""The OpenAPI document states what the settings make the service enforce (api/contract.py), and a method a
resource does not have is answered 405 with every method it has."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from api_helpers import AUTH, assert_problem, make_settings
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app
from softsig_service.experiments.campaign_spec import TABLE1_CELLS


def _document(tmp_path: Path, **settings: Any) -> dict[str, Any]:
    return create_app(make_settings(tmp_path, **settings)).openapi()


def _if_match(operation: dict[str, Any]) -> dict[str, Any]:
    return next(p for p in operation["parameters"] if p["name"] == "If-Match")


@pytest.mark.parametrize("read_auth", [False, True])
def test_reads_declare_the_key_exactly_when_they_need_it(tmp_path: Path, read_auth: bool) -> None:
    doc = _document(tmp_path, read_auth=read_auth)
    reads = [op for path, item in doc["paths"].items() if path.startswith("/v1/") for m, op in item.items()
             if m == "get"]  # fmt: skip
    assert len(reads) >= 10
    for op in reads:
        assert ("security" in op) is read_auth and ("401" in op["responses"]) is read_auth, op["operationId"]
    writes = [op for item in doc["paths"].values() for m, op in item.items() if m in ("post", "put", "delete")]
    assert all("security" in op and "401" in op["responses"] for op in writes if op["operationId"] != "readyz")
    with TestClient(create_app(make_settings(tmp_path / "svc", read_auth=read_auth))) as client:
        assert client.get("/v1/hands").status_code == (401 if read_auth else 200)


@pytest.mark.parametrize("required", [False, True])
def test_if_match_is_required_exactly_when_the_service_requires_it(tmp_path: Path, required: bool) -> None:
    doc = _document(tmp_path, require_if_match=required)
    hand = doc["paths"]["/v1/hands/{hand}"]
    assert _if_match(hand["put"])["required"] is required and _if_match(hand["delete"])["required"] is required
    closure = doc["paths"]["/v1/hands/{hand}/signatures/closure"]["post"]
    assert _if_match(closure)["required"] is False  # optional there, whatever the setting


@pytest.mark.parametrize("cap", [18, 360, 2000])
def test_trials_are_bounded_as_the_service_caps_them(tmp_path: Path, cap: int) -> None:
    schemas = _document(tmp_path, max_job_trials=cap)["components"]["schemas"]
    assert schemas["ValidationIn"]["properties"]["trials"]["maximum"] == cap
    experiment = schemas["ExperimentIn"]
    assert experiment["properties"]["trials"]["maximum"] == cap // TABLE1_CELLS
    # the default, 20 per cell, is above the cap of 18 or 360 trials: leaving trials out is refused, so required
    assert ("trials" in experiment.get("required", [])) is (cap // TABLE1_CELLS < 20)
    with TestClient(create_app(make_settings(tmp_path / "svc", max_job_trials=cap))) as client:
        refused = client.post("/v1/experiments", json={"trials": cap // TABLE1_CELLS + 1}, headers=AUTH)
        assert_problem(refused, 422, "trials")


@pytest.mark.parametrize(
    ("method", "path", "allowed"),
    [
        ("OPTIONS", "/v1/hands/parallel_gripper", "DELETE, GET, PUT"),
        ("PATCH", "/v1/plans", "GET, POST"),
        ("GET", "/v1/hands/parallel_gripper/signatures/stiffness", "POST"),
        ("PUT", "/v1/hands/parallel_gripper/signatures/3", "GET"),
        ("OPTIONS", "/v1/hands/archive", "POST"),  # the archive route's resource, not a hand named "archive"
    ],
)
def test_a_method_a_resource_lacks_is_405_naming_every_method_it_has(
    tmp_path: Path, method: str, path: str, allowed: str
) -> None:
    with TestClient(create_app(make_settings(tmp_path))) as client:
        response = client.request(method, path, headers=AUTH)
    assert_problem(response, 405)
    assert response.headers["allow"] == allowed


def test_a_method_the_framework_route_lacks_names_its_methods(tmp_path: Path) -> None:
    with TestClient(create_app(make_settings(tmp_path))) as client:
        response = client.post("/openapi.json")
    assert_problem(response, 405)
    assert "GET" in response.headers["allow"].split(", ")
