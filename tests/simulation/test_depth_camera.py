"""The simulated depth camera: exact depth of a plane, a cloud in the optical frame that tf brings back onto the
scene, and the whole path a robot stack takes, rendered: a tabletop with a clutter object, segmented, the box
picked and planned, the plan checked against the true box."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softsig_service.geometry.quaternions import matrix_to_quat
from softsig_service.objects import builtin_object, cylinder, object_from_json
from softsig_service.objects.frames import frame_transforms
from softsig_service.planning.planner import Planner
from softsig_service.planning.request import PlanRequest
from softsig_service.simulation.depth_camera import DepthCamera, depth_to_points, look_at, render_depth

EXACT = DepthCamera(noise_at_0_6m=0.0)
CAMERA = look_at([0.5, -0.45, 0.55], [0.5, 0.0, 0.0])  # in front of the table, above it, looking at the box


def _world(points: np.ndarray, T: np.ndarray) -> np.ndarray:
    return np.asarray(points @ T[:3, :3].T + T[:3, 3])


@pytest.mark.parametrize("table", [0.0, -0.05])
def test_a_camera_looking_down_sees_the_table_at_its_height(table: float) -> None:
    T = look_at([0.5, 0.0, 0.6], [0.5, 0.0, table])
    depth = render_depth([], T, EXACT, table_height=table)
    assert np.allclose(depth, 0.6 - table, atol=2e-5)  # a plane facing the camera is at one depth
    points = _world(depth_to_points(depth, EXACT), T)
    assert np.allclose(points[:, 2], table, atol=2e-5)
    half_width = (0.6 - table) * math.tan(EXACT.fovy / 2) * EXACT.width / EXACT.height
    assert np.ptp(points[:, 0]) == pytest.approx(2 * half_width, rel=0.01)


def _scene() -> tuple[list, np.ndarray]:
    box = builtin_object("box", x=0.5, y=0.0, yaw=0.3)
    clutter = cylinder(0.03, 0.12, 0.2, standing=True, x=0.5, y=0.16)
    return [box, clutter], depth_to_points(render_depth([box, clutter], CAMERA, DepthCamera(), seed=1))


def _camera_frame() -> dict:
    w, x, y, z = matrix_to_quat(CAMERA[:3, :3])
    p = CAMERA[:3, 3]
    return {"position": {"x": p[0], "y": p[1], "z": p[2]}, "orientation": {"x": x, "y": y, "z": z, "w": w}}


@pytest.mark.parametrize("hand", ["parallel_gripper", "pisa_iit_softhand"])
def test_a_rendered_tabletop_is_segmented_picked_and_planned_for_the_true_box(hand: str) -> None:
    (box, clutter), cloud = _scene()
    spec = {"kind": "tabletop", "points": cloud.tolist(), "frame_id": "camera_depth_optical_frame", "mass": 0.15,
            "pick": {"near": {"x": 0.5, "y": 0.0, "z": 0.0}}}  # fmt: skip
    frames = frame_transforms({"camera_depth_optical_frame": _camera_frame()})
    seen = object_from_json(spec, frames=frames)
    # the box's top and the faces towards the camera: the solid is the box, a few mm larger where the depth noise
    # (1.5 mm at 0.6 m) puts its outermost points
    assert abs(seen.extent_major - 0.16) < 0.008 and abs(seen.extent_minor - 0.06) < 0.008
    assert 0.0 < seen.height - 0.05 < 0.007 and np.linalg.norm(seen.center[:2] - box.center[:2]) < 0.005
    assert abs(abs(float(seen.o1 @ box.o1)) - 1.0) < 1e-3  # the same major axis
    planner = Planner()
    from softsig_service.objects.parse import tabletop_objects

    _, others, _ = tabletop_objects(spec, frames)
    plan = planner.plan(PlanRequest(hand=hand, obj=seen, strategy="C", obstacles=tuple(others)))
    assert plan.success, plan.reasons
    true = PlanRequest(hand=hand, obj=box, strategy="C", obstacles=(clutter,))
    assert planner.check_wrist_pose(true, plan.grasp_pose) == []  # feasible against the true box and cylinder
    exact = planner.plan(true)
    assert np.linalg.norm(plan.grasp_pose[:3, 3] - exact.grasp_pose[:3, 3]) < 0.01


def test_the_optical_frame_looks_at_its_target_with_the_image_down_towards_the_floor() -> None:
    T = look_at([0.5, -0.45, 0.55], [0.5, 0.0, 0.0])
    z = np.array([0.0, 0.45, -0.55]) / np.linalg.norm([0.0, 0.45, -0.55])
    assert np.allclose(T[:3, 2], z) and T[:3, 1] @ [0.0, 0.0, -1.0] > 0.5  # optical y: down in the image
    assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3)) and np.linalg.det(T[:3, :3]) > 0.99
    assert EXACT.matrix[0, 2] == (EXACT.width - 1) / 2  # pixel centres at whole numbers (ROS, OpenCV)
