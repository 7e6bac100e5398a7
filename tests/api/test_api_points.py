"""Objects as a camera sees them, over REST: a segmented point cloud in the camera's optical frame, the frame's pose
given as tf gives it, on a table at a stated height; the documented maxima fit the default body limit; bad clouds
and frames are 422 naming the field."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from api_helpers import AUTH, assert_problem
from fastapi.testclient import TestClient

from softsig_service.config import Settings
from softsig_service.geometry.quaternions import matrix_to_quat
from softsig_service.geometry.transforms import rpy_to_matrix
from softsig_service.objects.cloud import MAX_POINTS
from softsig_service.objects.schema import MAX_TABLETOP_POINTS

SIZE = (0.16, 0.06, 0.05)  # the built-in box [m]
CAMERA_R = rpy_to_matrix(-2.3, 0.05, 0.4)  # an optical frame (z forward) looking down at the table from the front
CAMERA_T = np.array([0.45, -0.45, 0.55])


def _seen_box(centre: tuple[float, float, float], n: int = 2500, seed: int = 0) -> np.ndarray:
    """What a camera in front of and above the box sees of it, in base_link: the top and the front face."""
    sx, sy, sz = SIZE
    rng = np.random.default_rng(seed)
    top = np.c_[rng.uniform(-sx / 2, sx / 2, n), rng.uniform(-sy / 2, sy / 2, n), np.full(n, sz / 2)]
    front = np.c_[rng.uniform(-sx / 2, sx / 2, n), np.full(n, -sy / 2), rng.uniform(-sz / 2, sz / 2, n)]
    corners = np.array([[a * sx / 2, b * sy / 2, sz / 2] for a in (-1, 1) for b in (-1, 1)])
    return np.vstack([top, front, corners]) + np.asarray(centre)


def _camera_frame() -> dict[str, Any]:
    w, x, y, z = matrix_to_quat(CAMERA_R)
    return {
        "position": dict(zip("xyz", CAMERA_T.tolist(), strict=True)),
        "orientation": {"x": x, "y": y, "z": z, "w": w},
    }


def _in_camera(points: np.ndarray) -> list[list[float]]:
    return ((points - CAMERA_T) @ CAMERA_R).tolist()  # p_cam = R^T (p - t)


def _plan(api: TestClient, obj: dict[str, Any], **extra: Any) -> dict[str, Any]:
    body = {"hand": "parallel_gripper", "object": obj, "strategy": "S", "store": False, **extra}
    r = api.post("/v1/plans", json=body, headers=AUTH)
    assert r.status_code == 200, r.text
    return dict(r.json())


def _position(plan: dict[str, Any]) -> np.ndarray:
    p = plan["grasp_pose"]["position"]
    return np.array([p["x"], p["y"], p["z"]])


@pytest.mark.parametrize("table", [0.0, -0.08])  # the robot on the table, or on a stand beside it
def test_a_cloud_in_the_cameras_frame_plans_as_the_box_it_shows(api: TestClient, table: float) -> None:
    centre = (0.5, 0.05, table + SIZE[2] / 2)
    cloud = {"kind": "points", "points": _in_camera(_seen_box(centre)), "frame_id": "camera_color_optical_frame",
             "mass": 0.15, "filter_outliers": False}  # fmt: skip
    plan = _plan(api, cloud, frames={"camera_color_optical_frame": _camera_frame()}, table={"height": table})
    box = _plan(api, {"kind": "box", "size": list(SIZE), "mass": 0.15, "pose": {"x": 0.5, "y": 0.05}},
                table={"height": table})  # fmt: skip
    assert plan["success"] and box["success"], (plan["reasons"], box["reasons"])
    assert np.linalg.norm(_position(plan) - _position(box)) < 1e-6  # the solid of what the camera saw is the box
    assert plan["object"]["kind"] == "mesh"  # the plan states the solid it planned with
    vertices = np.array(plan["object"]["vertices"])
    assert np.allclose(np.ptp(vertices, axis=0), SIZE, atol=1e-9)


def test_the_same_cloud_in_base_link_plans_alike(api: TestClient) -> None:
    points = _seen_box((0.5, 0.05, SIZE[2] / 2))
    seen = _plan(api, {"kind": "points", "points": _in_camera(points), "frame_id": "cam", "mass": 0.15},
                 frames={"cam": _camera_frame()})  # fmt: skip
    given = _plan(api, {"kind": "points", "points": points.tolist(), "mass": 0.15})
    filtered = _plan(api, {"kind": "points", "points": points.tolist(), "mass": 0.15, "filter_outliers": False})
    # the outlier filter drops a few isolated points on the edges (the top's corners): the solid moves by less
    # than the sampling spacing (~2 mm here)
    assert np.linalg.norm(_position(given) - _position(filtered)) < 5e-4
    assert np.linalg.norm(_position(seen) - _position(given)) < 1e-6


@pytest.mark.parametrize(
    ("obj", "extra", "field"),
    [
        ({"kind": "points", "points": [[0.5, 0, 0.01]] * 3, "mass": 0.1}, {}, "object.points"),
        ({"kind": "points", "points": [[0.4 + 0.01 * k, 0.0, 0.0] for k in range(20)], "mass": 0.1}, {},
         "object.points"),
        ({"kind": "points", "points": _seen_box((0.5, 0, 0.025)).tolist(), "frame_id": "kinect", "mass": 0.1},
         {"frames": {"cam": _camera_frame()}}, "object.frame_id"),
        ({"kind": "points", "points": _seen_box((0.5, 0, 0.025)).tolist(), "frame_id": "cam", "mass": 0.1},
         {"frames": {"cam": {**_camera_frame(), "orientation": {"x": 0.5, "y": 0.5, "z": 0.0, "w": 0.0}}}},
         "frames.cam.orientation"),
        ({"kind": "box", "size": list(SIZE), "mass": 0.1}, {"frames": {"base_link": _camera_frame()}},
         "frames.base_link"),
    ],
)  # fmt: skip
def test_bad_clouds_and_frames_are_422_naming_the_field(
    api: TestClient, obj: dict[str, Any], extra: dict[str, Any], field: str
) -> None:
    body = {"hand": "parallel_gripper", "object": obj, "strategy": "S", "store": False, **extra}
    problem = assert_problem(api.post("/v1/plans", json=body, headers=AUTH), 422)
    assert problem["field"] == field, problem


def test_a_nan_in_a_cloud_is_refused(api: TestClient) -> None:
    text = json.dumps({"hand": "parallel_gripper", "strategy": "S", "object": {
        "kind": "points", "mass": 0.1, "points": [[0.5, 0.0, 0.01]] * 5 + [[float("nan"), 0.0, 0.0]]}})  # fmt: skip
    r = api.post("/v1/plans", content=text, headers={**AUTH, "Content-Type": "application/json"})
    assert assert_problem(r, 422)["field"] == "object.points[5][0]"


def _worst_number(k: int) -> float:
    """A coordinate within the schema's bounds whose JSON is as long as any: 17 significant digits, a sign and an
    exponent (``-1.2345678901234567e-05``)."""
    return -(1.2345678901234567 + k * 1e-16) * 1e-5


def test_the_documented_maxima_fit_the_default_body_limit() -> None:
    limit = Settings().max_body_bytes
    point = [_worst_number(0)] * 3
    cloud = {"hand": "pisa_iit_softhand", "strategy": "C", "object": {"kind": "points", "mass": 1000.0,
             "points": [point] * MAX_POINTS, "frame_id": "camera_color_optical_frame", "name": "x" * 64}}  # fmt: skip
    mesh = {"hand": "pisa_iit_softhand", "strategy": "C", "object": {"kind": "mesh", "mass": 1000.0,
            "vertices": [point] * 100_000, "faces": [[99_999, 99_998, 99_997]] * 200_000}}  # fmt: skip
    tabletop = {"hand": "pisa_iit_softhand", "strategy": "C", "object": {"kind": "tabletop", "mass": 1000.0,
                "points": [point] * MAX_TABLETOP_POINTS, "frame_id": "camera_color_optical_frame",
                "pick": {"near": {"x": _worst_number(1), "y": _worst_number(2), "z": _worst_number(3)}}}}  # fmt: skip
    for body in (cloud, mesh, tabletop):
        assert len(json.dumps(body)) < limit


def test_a_cloud_of_the_most_points_plans(api: TestClient) -> None:
    rng = np.random.default_rng(3)
    n = MAX_POINTS
    points = _seen_box((0.5, 0.0, SIZE[2] / 2), n=n // 2 - 2)
    points = points + rng.normal(0.0, 0.0005, points.shape)
    assert len(points) == n
    text = json.dumps({"hand": "parallel_gripper", "strategy": "S", "store": False,
                       "object": {"kind": "points", "mass": 0.15, "points": points.tolist()}})  # fmt: skip
    assert len(text) < Settings().max_body_bytes
    r = api.post("/v1/plans", content=text, headers={**AUTH, "Content-Type": "application/json"})
    assert r.status_code == 200 and r.json()["success"], r.text[:500]
    extents = np.ptp(np.array(r.json()["object"]["vertices"]), axis=0)
    assert np.all(np.abs(extents - SIZE) < 0.004), extents  # noise of 0.5 mm, outliers filtered
    assert math.isclose(r.json()["object"]["mass"], 0.15)


def test_a_validation_simulates_the_clouds_solid(api: TestClient) -> None:
    """The validation job gets the object in base_link: the cloud's solid, as a mesh, over the stated table."""
    from api_helpers import wait_for

    cloud = {"kind": "points", "points": _in_camera(_seen_box((0.5, 0.0, -0.08 + SIZE[2] / 2))), "frame_id": "cam",
             "mass": 0.15}  # fmt: skip
    body = {"hand": "parallel_gripper", "object": cloud, "strategy": "S", "trials": 1,
            "frames": {"cam": _camera_frame()}, "table": {"height": -0.08}}  # fmt: skip
    r = api.post("/v1/validations", json=body, headers=AUTH)
    assert r.status_code == 202, r.text
    assert r.json()["params"]["object"]["kind"] == "mesh" and r.json()["params"]["table_height"] == -0.08

    def finished() -> dict[str, Any] | None:
        job: dict[str, Any] = api.get(f"/v1/jobs/{r.json()['id']}").json()
        return job if job["status"] not in ("queued", "running") else None

    job = wait_for(finished, timeout=240)
    assert job["status"] == "succeeded", job
    details = api.get(f"/v1/jobs/{job['id']}/files/validation.json").json()["details"][0]
    assert details["plan_reasons"] == [], details
