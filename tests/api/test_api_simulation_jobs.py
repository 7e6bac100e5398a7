"""Validations, experiments and stiffness signatures as jobs: 202 + Location, the job's result, its files."""

from __future__ import annotations

import io
from typing import Any

import numpy as np
import pytest
from api_helpers import AUTH, assert_problem, wait_for
from fastapi.testclient import TestClient
from PIL import Image

from softsig_service.gl_backend import render_unavailable_reason
from softsig_service.simulation.diagnosis import PHASES
from softsig_service.simulation.keyframes import PANEL_SIZE, TITLE_HEIGHT


def finished(client: TestClient, job_id: str) -> dict[str, Any] | None:
    job: dict[str, Any] = client.get(f"/v1/jobs/{job_id}").json()
    return job if job["status"] not in ("queued", "running") else None


def test_validation_job(api: TestClient) -> None:
    body = {"hand": "pisa_iit_softhand", "object": {"kind": "builtin", "name": "box"}, "strategy": "C", "trials": 2,
            "seed": 3, "sigma_r": 0.1, "sigma_t": 0.01}  # fmt: skip
    r = api.post("/v1/validations", json=body, headers=AUTH)
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    assert r.headers["location"] == f"/v1/jobs/{job_id}" and r.json()["kind"] == "validation"
    assert "hand_ref" not in r.json()["params"], "server paths stay private"
    job = wait_for(lambda: finished(api, job_id), timeout=240)
    assert job["status"] == "succeeded", job
    result = job["result"]
    assert result["trials"] == 2 and len(result["outcomes"]) == 2
    assert 0 <= result["successes"] <= 2
    assert all({"seed", "success", "reason", "lift_height"} <= set(o) for o in result["outcomes"])
    names = {f["name"] for f in api.get(f"/v1/jobs/{job_id}/files").json()["items"]}
    assert {"validation.json", "outcomes.csv"} <= names
    assert "keyframes" not in result and not any(n.startswith("keyframes/") for n in names), "rendered unasked"
    csv = api.get(f"/v1/jobs/{job_id}/files/outcomes.csv").text
    assert csv.splitlines()[0] == "trial,seed,success,reason,lift_height" and len(csv.splitlines()) == 3


@pytest.mark.skipif(render_unavailable_reason() is not None, reason="no OpenGL backend for rendering")
def test_validation_job_with_keyframes_links_a_strip_per_trial(api: TestClient) -> None:
    body = {"hand": "parallel_gripper", "object": {"kind": "builtin", "name": "box"}, "strategy": "C", "trials": 2,
            "keyframes": True}  # fmt: skip
    r = api.post("/v1/validations", json=body, headers=AUTH)
    assert r.status_code == 202, r.text
    job = wait_for(lambda: finished(api, r.json()["id"]), timeout=240)
    assert job["status"] == "succeeded", job
    links = job["result"]["keyframes"]
    assert links == [f"/v1/jobs/{job['id']}/files/keyframes/trial_{k:03d}.png" for k in range(2)]
    listed = {f["url"]: f for f in api.get(f"/v1/jobs/{job['id']}/files").json()["items"]}
    width, height = PANEL_SIZE
    for url, outcome in zip(links, job["result"]["outcomes"], strict=True):
        assert listed[url]["media_type"] == "image/png"
        got = api.get(url)
        assert got.status_code == 200 and got.headers["content-type"] == "image/png"
        image = np.asarray(Image.open(io.BytesIO(got.content)).convert("RGB"))
        assert outcome["success"]  # the gripper carries the box: every phase ran, a panel each
        assert image.shape == (TITLE_HEIGHT + height, len(PHASES) * width, 3)
        assert image[TITLE_HEIGHT:].std() > 20.0
    assert_problem(api.post("/v1/validations", json={**body, "keyframes": "yes"}, headers=AUTH), 422, "keyframes")


def test_job_submissions_check_input_and_caps(api: TestClient) -> None:
    ok = {"hand": "pisa_iit_softhand", "object": {"kind": "builtin", "name": "box"}, "strategy": "C"}
    assert_problem(api.post("/v1/validations", json={**ok, "trials": 10**5}, headers=AUTH), 422, "trials")
    assert_problem(api.post("/v1/validations", json={**ok, "hand": "nobody"}, headers=AUTH), 422, "hand")
    assert_problem(api.post("/v1/validations", json={**ok, "sigma_r": -1}, headers=AUTH), 422, "sigma_r")
    bad_obj = {**ok, "object": {"kind": "box", "size": [0.1, 0.1, 0.1], "mass": 1, "pose": {"z": -1.0}}}
    assert_problem(api.post("/v1/validations", json=bad_obj, headers=AUTH), 422, "object.pose.z")
    assert_problem(api.post("/v1/validations", json=ok), 401, "X-API-Key")
    assert_problem(api.post("/v1/experiments", json={"trials": 500}, headers=AUTH), 422, "trials")
    assert_problem(api.post("/v1/experiments", json={"name": "table2"}, headers=AUTH), 422, "name")


@pytest.mark.slow
def test_experiment_job(api: TestClient) -> None:
    r = api.post("/v1/experiments", json={"trials": 1, "seed": 1, "workers": 2}, headers=AUTH)
    assert r.status_code == 202, r.text
    job = wait_for(lambda: finished(api, r.json()["id"]), timeout=900)
    assert job["status"] == "succeeded", job
    assert job["result"]["complete"] is True and job["result"]["ran"] == 18
    names = {f["name"] for f in api.get(f"/v1/jobs/{job['id']}/files").json()["items"]}
    assert {"report.md", "results.csv", "results.json", "table1.png"} <= names
    report = api.get(f"/v1/jobs/{job['id']}/files/report.md")
    assert report.headers["content-type"].startswith("text/markdown") and "|" in report.text


def test_stiffness_signature_job_stores_a_version(api: TestClient) -> None:
    r = api.post(
        "/v1/hands/parallel_gripper/signatures/stiffness",
        json={"object": {"kind": "builtin", "name": "box"}},
        headers=AUTH,
    )
    assert r.status_code == 202, r.text
    assert r.headers["location"].startswith("/v1/jobs/") and r.json()["kind"] == "stiffness_signature"
    job = wait_for(lambda: finished(api, r.json()["id"]), timeout=900)
    assert job["status"] == "succeeded", job
    version = job["result"]["version"]
    sig = api.get(f"/v1/hands/parallel_gripper/signatures/{version}").json()
    assert sig["kind"] == "stiffness" and sig["object"] == "box" and sig["cs_method"] is None
    K = sig["signature"]["K"]
    assert len(K) == 6 and all(len(row) == 6 for row in K)
    assert all(abs(K[i][j] - K[j][i]) <= 1e-6 * (1 + abs(K[i][j])) for i in range(6) for j in range(6))
    assert (
        api.get("/v1/hands/parallel_gripper/signatures/latest", params={"kind": "stiffness"}).json()["version"]
        == version
    )
