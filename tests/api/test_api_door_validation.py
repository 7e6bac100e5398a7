"""Validate at the door: what a job would reject is 422 at submission, bodies are strict, every 4xx is a problem."""

from __future__ import annotations

from typing import Any

import pytest
from api_helpers import AUTH, assert_problem
from fastapi.testclient import TestClient

from softsig_service.errors import InvalidInput
from softsig_service.objects import object_from_json

BOX: dict[str, Any] = {"kind": "box", "size": [0.05, 0.05, 0.05], "mass": 0.1}
TET = {"kind": "mesh", "mass": 0.1, "vertices": [[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0], [0, 0, 0.05]]}


@pytest.mark.parametrize(
    ("obj", "field"),
    [
        ({**BOX, "size": [5e-324, 0.05, 0.05]}, "object.size[0]"),
        ({**BOX, "mass": 5e-324}, "object.mass"),
        ({"kind": "sphere", "radius": 1e-300, "mass": 0.1}, "object.radius"),
        ({**TET, "faces": [[0, 0, 0], [0, 1, 3], [0, 3, 2], [1, 2, 3]]}, "object.faces"),
        ({**TET, "faces": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 9]]}, "object.faces"),
    ],
)
@pytest.mark.parametrize("route", ["/v1/validations", "/v1/plans"])
def test_what_a_job_rejects_is_422_at_submission(api: TestClient, route: str, obj: dict[str, Any], field: str) -> None:
    body = {"hand": "parallel_gripper", "object": obj, "strategy": "S"}
    response = api.post(route, json=body, headers=AUTH)
    problem = assert_problem(response, 422)
    assert str(problem["field"]).startswith(field), problem


def test_the_job_uses_the_same_validator() -> None:
    with pytest.raises(InvalidInput) as info:
        object_from_json({**BOX, "mass": 5e-324})
    assert info.value.field == "object.mass"


@pytest.mark.parametrize(
    ("route", "body", "field"),
    [
        ("/v1/plans", {"hand": "parallel_gripper", "object": BOX, "strategy": "S", "margin": "0.01"}, "margin"),
        ("/v1/plans", {"hand": "parallel_gripper", "object": BOX, "strategy": "S", "margin": False}, "margin"),
        ("/v1/plans", {"hand": "parallel_gripper", "object": BOX, "strategy": "S", "store": 1}, "store"),
        (
            "/v1/plans",
            {"hand": "parallel_gripper", "object": BOX, "strategy": "S", "current_q": ["0", 0, 0, 0, 0, 0]},
            "current_q[0]",
        ),
        ("/v1/validations", {"object": BOX, "strategy": "S", "trials": "2"}, "trials"),
        ("/v1/validations", {"object": BOX, "strategy": "S", "sigma_r": True}, "sigma_r"),
        ("/v1/validations", {"object": BOX, "strategy": "S", "trials": 2.5}, "trials"),
        ("/v1/validations", {"object": BOX, "strategy": "S", "trials": True}, "trials"),
        ("/v1/experiments", {"trials": "3"}, "trials"),
    ],
)
def test_bodies_are_strict(api: TestClient, route: str, body: dict[str, Any], field: str | None) -> None:
    problem = assert_problem(api.post(route, json=body, headers=AUTH), 422)
    if field is not None:
        assert problem["field"] == field, problem


@pytest.mark.parametrize(
    ("method", "path", "kwargs", "status"),
    [
        ("POST", "/v1/plans", {"content": b"{not json", "headers": {"Content-Type": "application/json"}}, 400),
        (
            "POST",
            "/v1/hands",
            {"content": b"--x\r\ngarbage", "headers": {"Content-Type": "multipart/form-data; boundary=x"}},
            422,
        ),
        (
            "POST",
            "/v1/hands",
            {"content": b"--x\r\ngarbage", "headers": {"Content-Type": "multipart/form-data"}},
            400,
        ),
        ("POST", "/v1/plans", {"content": b"{}", "headers": {"Content-Length": "abc"}}, 400),
        ("GET", "/v1/nowhere", {}, 404),
        ("PATCH", "/v1/plans", {}, 405),
        ("GET", "/v1/plans?limit=abc", {}, 422),
    ],
)
def test_every_4xx_is_a_problem(api: TestClient, method: str, path: str, kwargs: dict[str, Any], status: int) -> None:
    extra = dict(kwargs)  # the parameters are shared by both database backends: leave them as they are
    headers = {**AUTH, **extra.pop("headers", {})}
    response = api.request(method, path, headers=headers, **extra)
    assert_problem(response, status)


def test_a_number_without_a_fractional_part_is_an_integer(api: TestClient) -> None:
    """JSON Schema's integer (the OpenAPI document's ``type: integer``) is any number whose fractional part is
    zero: ``1.0`` trials and vertex index ``2.0`` are taken as 1 and 2, as the document promises."""
    from softsig_service.api.schemas import ValidationIn

    tet = {**TET, "faces": [[0, 2.0, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]}
    body = ValidationIn.model_validate({"object": tet, "strategy": "S", "trials": 1.0, "seed": 7.0})
    assert (body.trials, body.seed) == (1, 7) and type(body.trials) is int
    assert body.object.faces is not None and body.object.faces[0] == (0, 2, 1)  # type: ignore[union-attr]
    plan = api.post("/v1/plans", json={"hand": "parallel_gripper", "object": BOX, "strategy": "R",
                                       "capture_version": 1.0}, headers=AUTH)  # fmt: skip
    # past the body's validation: the version 1 is looked up (the gripper has no capture model)
    assert plan.status_code == 422 and plan.json()["detail"] == "no such signature version", plan.text
    assert plan.json()["value"] == 1
