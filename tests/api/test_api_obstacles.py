"""Obstacles over REST: any object spec (a point cloud in a camera frame too) is an obstacle of the plan; a blocked
plan names the obstacle; a bad obstacle is 422 naming its field."""

from __future__ import annotations

from typing import Any

import numpy as np
from api_helpers import AUTH, assert_problem
from fastapi.testclient import TestClient

BOX = {"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.0, "yaw": 0.0}}


def _post(y: float) -> dict[str, Any]:
    return {"kind": "box", "size": [0.10, 0.04, 0.12], "mass": 0.5, "pose": {"x": 0.5, "y": y}}


def _cloud_post(y: float) -> dict[str, Any]:
    """The same block as a cloud of its top and its sides, in a frame 1 m above base_link turned by pi about x."""
    rng = np.random.default_rng(0)
    n = 400
    top = np.c_[rng.uniform(-0.05, 0.05, n), rng.uniform(-0.02, 0.02, n), np.full(n, 0.12)]
    side = np.c_[rng.uniform(-0.05, 0.05, n), np.full(n, -0.02), rng.uniform(0, 0.12, n)]
    corners = np.array([[a * 0.05, b * 0.02, 0.12] for a in (-1, 1) for b in (-1, 1)])
    world = np.vstack([top, side, corners]) + np.array([0.5, y, 0.0])
    in_frame = (world - np.array([0.0, 0.0, 1.0])) * np.array([1.0, -1.0, -1.0])  # R_x(pi) is its own inverse
    return {"kind": "points", "points": in_frame.tolist(), "frame_id": "overhead", "mass": 0.5,
            "filter_outliers": False}  # fmt: skip


OVERHEAD = {"position": {"x": 0.0, "y": 0.0, "z": 1.0}, "orientation": {"x": 1.0, "y": 0.0, "z": 0.0, "w": 0.0}}


def _plan(api: TestClient, **extra: Any) -> dict[str, Any]:
    body = {"hand": "parallel_gripper", "object": BOX, "strategy": "S", "store": False, **extra}
    r = api.post("/v1/plans", json=body, headers=AUTH)
    assert r.status_code == 200, r.text
    return dict(r.json())


def test_obstacles_on_both_sides_are_named(api: TestClient) -> None:
    assert _plan(api)["success"]
    blocked = _plan(api, obstacles=[_post(-0.06), _post(0.6), _post(0.06)])
    assert not blocked["success"]
    assert blocked["reasons"] and set(blocked["reasons"]) <= {"collision:obstacle[0]", "collision:obstacle[2]"}


def test_a_cloud_obstacle_blocks_as_the_block_it_shows(api: TestClient) -> None:
    as_box = _plan(api, obstacles=[_post(0.06)])
    as_cloud = _plan(api, obstacles=[_cloud_post(0.06)], frames={"overhead": OVERHEAD})
    assert as_box["reasons"] == as_cloud["reasons"] == ["collision:obstacle[0]"]
    far = _plan(api, obstacles=[_cloud_post(0.5)], frames={"overhead": OVERHEAD})
    assert far["success"]


def test_a_bad_obstacle_is_422_naming_its_field(api: TestClient) -> None:
    body = {"hand": "parallel_gripper", "object": BOX, "strategy": "S",
            "obstacles": [_post(0.3), {**_post(0.4), "size": [0.1, 0.0, 0.1]}]}  # fmt: skip
    assert assert_problem(api.post("/v1/plans", json=body, headers=AUTH), 422)["field"] == "obstacles[1].size[1]"
    body["obstacles"] = [_cloud_post(0.3)]  # its frame is not given
    assert assert_problem(api.post("/v1/plans", json=body, headers=AUTH), 422)["field"] == "obstacles[0].frame_id"
    body["obstacles"] = [_post(0.3)] * 33
    assert assert_problem(api.post("/v1/plans", json=body, headers=AUTH), 422)["field"] == "obstacles"


def test_a_validation_plans_around_and_simulates_its_obstacles(api: TestClient) -> None:
    from api_helpers import wait_for

    body = {"hand": "parallel_gripper", "object": BOX, "strategy": "S", "trials": 1,
            "obstacles": [_cloud_post(0.06)], "frames": {"overhead": OVERHEAD}}  # fmt: skip
    r = api.post("/v1/validations", json=body, headers=AUTH)
    assert r.status_code == 202, r.text
    assert r.json()["params"]["obstacles"][0]["kind"] == "mesh"  # the cloud's solid, in base_link

    def finished() -> dict[str, Any] | None:
        job: dict[str, Any] = api.get(f"/v1/jobs/{r.json()['id']}").json()
        return job if job["status"] not in ("queued", "running") else None

    job = wait_for(finished, timeout=240)
    assert job["status"] == "succeeded", job
    assert job["result"]["outcomes"][0]["reason"] == "collision:obstacle[0]"  # planned around: nothing was left
