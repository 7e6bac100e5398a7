"""A whole tabletop cloud: the table plane found by RANSAC, the objects by DBSCAN; the segmentation endpoint shows
them, a tabletop object plans for the picked cluster with the others as obstacles; clouds with no table, a tilted
plane or nothing on the table are 422 naming the field."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from api_helpers import AUTH, assert_problem
from fastapi.testclient import TestClient

TABLE = -0.02  # [m] the table top in base_link
OBJECTS = [((0.5, 0.0), (0.16, 0.06, 0.05)), ((0.5, 0.09), (0.06, 0.06, 0.10)), ((0.62, -0.18), (0.08, 0.08, 0.03))]
"""(x, y) and size [m] of the boxes: the built-in box, a tall box 3 cm beside it, a flat one apart."""


def _tabletop(seed: int = 0, noise: float = 0.001) -> np.ndarray:
    """A table (0.7 x 0.8 m) and three boxes, each seen from above (top and the face towards -y), in base_link."""
    rng = np.random.default_rng(seed)
    table = np.c_[rng.uniform(0.2, 0.9, 40_000), rng.uniform(-0.4, 0.4, 40_000), np.full(40_000, TABLE)]
    parts = [table]
    for (x, y), (sx, sy, sz) in OBJECTS:
        n = int(40_000 * sx * sy) + 400
        top = np.c_[rng.uniform(-sx / 2, sx / 2, n), rng.uniform(-sy / 2, sy / 2, n), np.full(n, sz)]
        front = np.c_[rng.uniform(-sx / 2, sx / 2, n), np.full(n, -sy / 2), rng.uniform(0, sz, n)]
        parts.append(np.vstack([top, front]) + np.array([x, y, TABLE]))
    cloud = np.vstack(parts)
    return cloud + rng.normal(0.0, noise, cloud.shape)


def test_the_segmentation_finds_the_table_and_the_three_boxes(api: TestClient) -> None:
    r = api.post("/v1/segmentations", json={"points": _tabletop().tolist()}, headers=AUTH)
    assert r.status_code == 200, r.text
    seg = r.json()
    assert abs(seg["table"]["height"] - TABLE) < 5e-4 and seg["table"]["tilt"] < 0.01
    assert len(seg["clusters"]) == 3
    for (x, y), (sx, sy, sz) in OBJECTS:
        c = min(seg["clusters"], key=lambda c: (c["centroid"]["x"] - x) ** 2 + (c["centroid"]["y"] - y) ** 2)
        extents = np.ptp(np.array(c["solid"]["vertices"]), axis=0)  # the boxes are axis-aligned
        assert np.all(np.abs(extents - [sx, sy, sz]) < 0.006), (extents, (sx, sy, sz))
        assert abs(c["height"] - sz) < 0.006  # the solid stands on the table found
        assert c["extent_minor"] <= c["extent_major"]


def _plan(api: TestClient, obj: dict[str, Any], **extra: Any) -> dict[str, Any]:
    body = {"hand": "parallel_gripper", "object": obj, "strategy": "S", "store": False, **extra}
    r = api.post("/v1/plans", json=body, headers=AUTH)
    assert r.status_code == 200, r.text
    return dict(r.json())


def _box(k: int) -> dict[str, Any]:
    (x, y), size = OBJECTS[k]
    return {"kind": "box", "size": list(size), "mass": 0.15, "pose": {"x": x, "y": y}}


def test_a_tabletop_plans_the_picked_box_with_the_others_as_obstacles(api: TestClient) -> None:
    cloud = _tabletop().tolist()

    def pick(k: int) -> dict[str, Any]:
        (x, y), _ = OBJECTS[k]
        return _plan(api, {"kind": "tabletop", "points": cloud, "mass": 0.15, "pick": {"near": {"x": x, "y": y,
                                                                                              "z": 0.0}}})  # fmt: skip

    flat = pick(2)
    assert flat["success"], flat["reasons"]
    assert np.all(np.abs(np.ptp(np.array(flat["object"]["vertices"]), axis=0) - OBJECTS[2][1]) < 0.006)
    assert abs(flat["object"]["pose"]["x"] - 0.62) < 0.005 and abs(flat["object"]["pose"]["y"] + 0.18) < 0.005
    # the built-in box, with the tall box 3 cm beside it: the gripper's jaw would go through the tall box, exactly
    # as it does when the two others are stated as obstacles (in the tabletop's cluster order: flat, tall)
    boxed = pick(0)
    stated = _plan(api, _box(0), table={"height": TABLE}, obstacles=[_box(2), _box(1)])
    alone = _plan(api, _box(0), table={"height": TABLE})
    assert alone["success"]
    assert not boxed["success"] and boxed["reasons"] == stated["reasons"] == ["collision:obstacle[1]"]


@pytest.mark.parametrize(
    ("points", "field"),
    [
        (np.random.default_rng(0).uniform(0, 1, (2000, 3)), "object.points"),  # no plane holds enough
        (
            np.c_[np.random.default_rng(0).uniform(0.2, 0.9, (2000, 2)), np.zeros(2000)],
            "object.points",
        ),  # nothing on it
    ],
)
def test_a_cloud_without_a_table_or_objects_is_422(api: TestClient, points: np.ndarray, field: str) -> None:
    body = {"hand": "parallel_gripper", "strategy": "S", "object": {"kind": "tabletop", "points": points.tolist(),
                                                                    "mass": 0.1}}  # fmt: skip
    assert assert_problem(api.post("/v1/plans", json=body, headers=AUTH), 422)["field"] == field


def test_a_tilted_plane_is_not_a_table(api: TestClient) -> None:
    cloud = _tabletop()
    tilt = 0.35  # rad about x: the camera's pose was wrong
    c, s = np.cos(tilt), np.sin(tilt)
    tilted = cloud @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]]).T
    r = api.post("/v1/segmentations", json={"points": tilted.tolist()}, headers=AUTH)
    assert "tilted" in assert_problem(r, 422, "points")["detail"]


def test_a_picked_index_out_of_range_is_named(api: TestClient) -> None:
    body = {"hand": "parallel_gripper", "strategy": "S",
            "object": {"kind": "tabletop", "points": _tabletop().tolist(), "mass": 0.1, "pick": {"index": 7}}}  # fmt: skip
    assert assert_problem(api.post("/v1/plans", json=body, headers=AUTH), 422)["field"] == "object.pick.index"


def test_a_rendered_depth_image_plans_over_rest(api: TestClient) -> None:
    """The simulated camera's cloud (every other pixel of a 640 x 480 depth image with a clutter object), in its
    optical frame with the frame's pose as tf gives it, plans the box."""
    from softsig_service.geometry.quaternions import matrix_to_quat
    from softsig_service.objects import builtin_object, cylinder
    from softsig_service.simulation.depth_camera import DepthCamera, depth_to_points, look_at, render_depth

    T = look_at([0.5, -0.45, 0.55], [0.5, 0.0, 0.0])
    scene = [builtin_object("box", x=0.5, y=0.0, yaw=0.3), cylinder(0.03, 0.12, 0.2, standing=True, x=0.5, y=0.16)]
    cloud = depth_to_points(render_depth(scene, T, DepthCamera(), seed=1), stride=2)
    w, x, y, z = matrix_to_quat(T[:3, :3])
    frame = {"position": dict(zip("xyz", T[:3, 3].tolist(), strict=True)), "orientation": {"x": x, "y": y, "z": z,
                                                                                          "w": w}}  # fmt: skip
    body = {"hand": "pisa_iit_softhand", "strategy": "C", "store": False,
            "object": {"kind": "tabletop", "points": cloud.tolist(), "frame_id": "camera_depth_optical_frame",
                       "mass": 0.15, "pick": {"near": {"x": 0.5, "y": 0.0, "z": 0.0}}},
            "frames": {"camera_depth_optical_frame": frame}}  # fmt: skip
    r = api.post("/v1/plans", json=body, headers=AUTH)
    assert r.status_code == 200 and r.json()["success"], r.text[:400]
    assert abs(r.json()["object"]["pose"]["x"] - 0.5) < 0.005 and abs(r.json()["object"]["pose"]["y"]) < 0.005


def test_a_flat_cluster_is_noise_not_a_refusal(api: TestClient) -> None:
    """A card standing edge-on beside the boxes (1 mm thick: nothing to grasp or hit) does not refuse the scene."""
    rng = np.random.default_rng(5)
    card = np.c_[rng.uniform(0.3, 0.4, 3000), np.full(3000, 0.3), rng.uniform(TABLE + 0.01, TABLE + 0.08, 3000)]
    r = api.post("/v1/segmentations", json={"points": np.vstack([_tabletop(), card]).tolist()}, headers=AUTH)
    assert r.status_code == 200, r.text
    assert len(r.json()["clusters"]) == 3 and r.json()["noise"] >= 3000
