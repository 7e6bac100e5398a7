"""The contract is as tight as the answers: every response object of the OpenAPI document is closed (no undeclared
key passes), real answers validate against their models, and a key the service would add without declaring it
is caught."""

from __future__ import annotations

from typing import Any

import pytest
from api_helpers import AUTH
from fastapi.testclient import TestClient
from pydantic import ValidationError

from softsig_service.api.plan_schemas import PlanOut
from softsig_service.api.schemas import HandOut, JobOut, SignatureOut

BOX = {"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.05, "yaw": 0.4}}


def _objects(schema: dict[str, Any], spec: dict[str, Any], seen: set[str]) -> list[tuple[str, dict[str, Any]]]:
    """Every named object schema reachable from ``schema`` (each reference followed once), with its name."""
    out: list[tuple[str, dict[str, Any]]] = []
    ref = schema.get("$ref")
    if ref is not None:
        name = ref.rsplit("/", 1)[1]
        if name in seen:
            return out
        seen.add(name)
        schema = spec["components"]["schemas"][name]
        out.append((name, schema))
    for sub in schema.get("properties", {}).values():
        out += _objects(sub, spec, seen)
    for key in ("items", "additionalProperties"):
        if isinstance(schema.get(key), dict):
            out += _objects(schema[key], spec, seen)
    for key in ("anyOf", "oneOf", "allOf"):
        for sub in schema.get(key, []):
            out += _objects(sub, spec, seen)
    return out


def test_every_response_object_is_closed(api: TestClient) -> None:
    spec = api.app.openapi()  # type: ignore[attr-defined]
    seen: set[str] = set()
    found: list[tuple[str, dict[str, Any]]] = []
    for item in spec["paths"].values():
        for op in item.values():
            for code, response in op.get("responses", {}).items():
                if code.startswith("2"):
                    for content in response.get("content", {}).values():
                        found += _objects(content.get("schema", {}), spec, seen)
    assert {name for name, _ in found} >= {"PlanOut", "Timing", "Solver", "ClosureCommand", "HandOut", "JobOut"}
    open_ = [name for name, s in found if s.get("properties") and s.get("additionalProperties") is not False]
    assert open_ == [], open_


def test_real_answers_validate_and_an_undeclared_key_does_not(api: TestClient) -> None:
    plan = api.post("/v1/plans", json={"hand": "parallel_gripper", "object": BOX, "strategy": "C"}, headers=AUTH)
    assert plan.status_code == 201, plan.text
    hand = api.get("/v1/hands/parallel_gripper")
    cs = api.post("/v1/hands/parallel_gripper/signatures/closure", json={}, headers=AUTH)
    job = api.post("/v1/validations", json={"hand": "parallel_gripper", "object": BOX, "strategy": "S",
                                            "trials": 1}, headers=AUTH)  # fmt: skip
    for model, response in ((PlanOut, plan), (HandOut, hand), (SignatureOut, cs), (JobOut, job)):
        body = response.json()
        model.model_validate(body)
        with pytest.raises(ValidationError, match="Extra inputs are not permitted"):
            model.model_validate({**body, "undeclared": 1})
    for part in ("timing", "solver", "closure", "quality", "approach"):
        with pytest.raises(ValidationError):
            PlanOut.model_validate({**plan.json(), part: {**plan.json()[part], "undeclared": 1}})
    api.post(f"/v1/jobs/{job.json()['id']}/cancel", headers=AUTH)


def test_every_plan_request_field_has_one_place() -> None:
    """Each field of PlanIn either reaches the planner under the same name (PLANNER_FIELDS, each a field of
    PlanRequest of the same meaning) or is resolved by the route (ROUTE_FIELDS): a new field cannot be dropped."""
    import dataclasses

    from softsig_service.api.plan_schemas import PlanIn
    from softsig_service.api.routes.plans import PLANNER_FIELDS, ROUTE_FIELDS
    from softsig_service.planning.request import PlanRequest

    assert set(PLANNER_FIELDS).isdisjoint(ROUTE_FIELDS)
    assert set(PLANNER_FIELDS) | set(ROUTE_FIELDS) == set(PlanIn.model_fields)
    assert set(PLANNER_FIELDS) <= {f.name for f in dataclasses.fields(PlanRequest)}


@pytest.mark.parametrize(
    ("field", "value", "seen"),
    [
        ("margin", 0.02, lambda p: p["quality"]["clearance"] >= 0.02 - 1e-9),
        ("approach_distance", 0.2, lambda p: abs(p["approach"]["desired_distance"] - 0.2) < 1e-12),
        ("cs_method", "pca", lambda p: p["solver"]["cs_method"] == "pca"),
        ("placement", "grasp_centre", lambda p: p["solver"]["placement"] == "grasp_centre"),
    ],
)
def test_a_plan_option_reaches_the_planner(api: TestClient, field: str, value: Any, seen: Any) -> None:
    body = {"hand": "parallel_gripper", "object": BOX, "strategy": "C", "store": False, field: value}
    r = api.post("/v1/plans", json=body, headers=AUTH)
    assert r.status_code == 200, r.text
    assert seen(r.json()), r.json()
