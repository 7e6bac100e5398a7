"""Strategy R through the API: the capture model as a signature job, then plans that use it."""

from __future__ import annotations

from typing import Any

from api_helpers import AUTH, assert_problem, wait_for
from fastapi.testclient import TestClient

BOX = {"kind": "builtin", "name": "box"}
GRID = {"n_theta": 2, "half_width": 0.01, "step": 0.01, "holdout": 2}


def _done(api: TestClient, job_id: str) -> dict[str, Any] | None:
    job: dict[str, Any] = api.get(f"/v1/jobs/{job_id}").json()
    return job if job["status"] not in ("queued", "running") else None


def test_capture_model_job_and_r_plans(api: TestClient) -> None:
    url = "/v1/hands/parallel_gripper/signatures/capture"
    plan = {"hand": "parallel_gripper", "object": BOX, "strategy": "R", "sigma_r": 0.1, "sigma_t": 0.01}
    shipped = api.post("/v1/plans", json=plan, headers=AUTH)  # before any job: the model shipped with the hand
    assert shipped.status_code == 201, shipped.text
    r = api.post(url, json={"object": BOX, **GRID}, headers=AUTH)
    assert r.status_code == 202, r.text
    job = wait_for(lambda: _done(api, r.json()["id"]), timeout=240)
    assert job["status"] == "succeeded", job
    version = job["result"]["version"]
    sig = api.get(f"/v1/hands/parallel_gripper/signatures/{version}").json()
    assert sig["kind"] == "capture" and sig["object"] == "box" and sig["params"]["grid"]["n_theta"] == 2
    model = sig["signature"]
    assert len(model["theta"]) == 2 and len(model["u"]) == 3 and model["meta"]["simulations"] == 2 * 9 + 2
    assert model["values"][1][1][1] == 1.0, "the box across the jaws at no offset is carried"
    files = {f["name"] for f in api.get(f"/v1/jobs/{job['id']}/files").json()["items"]}
    assert "capture_model.json" in files
    # R plans with it: the newest capture model of this object, or a named version
    for body in (plan, {**plan, "capture_version": version}, {**plan, "sigma_r": 0.0, "sigma_t": 0.0}):
        out = api.post("/v1/plans", json=body, headers=AUTH)
        assert out.status_code == 201, out.text
        data = out.json()
        assert data["strategy"] == "R" and data["success"] is True
        assert 0.0 <= data["quality"]["expected_capture"] <= 1.0
    # a capture model of another object, or not a capture model, is refused naming the field
    other = {**plan, "object": {"kind": "box", "size": [0.1, 0.05, 0.05], "mass": 0.2}}  # none stored or shipped
    assert_problem(api.post("/v1/plans", json=other, headers=AUTH), 422, "capture_version")
    closure = api.post("/v1/hands/parallel_gripper/signatures/closure", json={}, headers=AUTH).json()["version"]
    wrong = {**plan, "capture_version": closure}
    assert_problem(api.post("/v1/plans", json=wrong, headers=AUTH), 422, "capture_version")
    assert_problem(api.post("/v1/plans", json={**plan, "sigma_r": -1}, headers=AUTH), 422, "sigma_r")


def test_capture_model_requests_are_checked_at_the_door(api: TestClient) -> None:
    url = "/v1/hands/parallel_gripper/signatures/capture"
    assert_problem(api.post(url, json={"object": BOX, "step": 0.05, "half_width": 0.01}, headers=AUTH), 422,
                   "half_width")  # fmt: skip
    assert_problem(api.post(url, json={"object": BOX, "n_theta": 72, "half_width": 0.1, "step": 0.001},
                            headers=AUTH), 422, "n_theta")  # fmt: skip
    assert_problem(api.post(url, json={"object": BOX, "n_theta": "12"}, headers=AUTH), 422, "n_theta")
    assert_problem(api.post("/v1/hands/nope/signatures/capture", json={"object": BOX}, headers=AUTH), 404)
