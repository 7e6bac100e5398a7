"""Ranked grasps over REST: candidates and output_frame in a plan request; every grasp in the answer's frame with
its moveit_msgs/Grasp and trajectories; a stored ranked plan reads back the same and draws; bad values are 422."""

from __future__ import annotations

from typing import Any

import numpy as np
from api_helpers import AUTH, assert_problem
from fastapi.testclient import TestClient

from softsig_service.geometry.transforms import Pose

BOX = {"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.0, "yaw": 0.0}}
CAMERA = {"position": {"x": 0.5, "y": -0.45, "z": 0.55}, "orientation": {"x": -0.942, "y": 0.0, "z": 0.0, "w": 0.336}}


def _plan(api: TestClient, **extra: Any) -> Any:
    body = {"hand": "pisa_iit_softhand", "object": BOX, "strategy": "C", **extra}
    return api.post("/v1/plans", json=body, headers=AUTH)


def test_a_ranked_plan_in_the_camera_frame_reads_back_and_turns_back(api: TestClient) -> None:
    base = _plan(api, candidates=4, store=False).json()
    r = _plan(api, candidates=4, output_frame="camera_color_optical_frame",
              frames={"camera_color_optical_frame": CAMERA})  # fmt: skip
    assert r.status_code == 201, r.text
    plan = r.json()
    assert plan["output_frame"] == "camera_color_optical_frame" and len(plan["grasps"]) == 4
    assert [g["rank"] for g in plan["grasps"]] == [1, 2, 3, 4]
    assert plan["grasps"][0]["quality_model"] == "capture"  # the SoftHand ships a capture model of the box
    T = Pose.from_wire(plan["output_frame_pose"]).matrix()
    for got, ref in zip(plan["grasps"], base["grasps"], strict=True):
        assert got["grasp_pose"]["frame_id"] == "camera_color_optical_frame"
        assert got["moveit_grasp"]["grasp_pose"]["header"]["frame_id"] == "camera_color_optical_frame"
        back = T @ Pose.from_wire(got["grasp_pose"]).matrix()
        assert np.allclose(back, Pose.from_wire(ref["grasp_pose"]).matrix(), atol=1e-9)
        assert got["approach_trajectory"]["joint_names"][0] == "shoulder_pan_joint"
    again = api.get(plan["links"]["self"])
    assert again.status_code == 200 and again.json()["grasps"] == plan["grasps"]
    image = api.get(plan["links"]["self"] + "/image.png")
    assert image.status_code == 200 and image.content[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_ur_base_frame_is_base_link_turned_a_half_turn(api: TestClient) -> None:
    a = _plan(api, store=False).json()["grasp_pose"]["position"]
    b = _plan(api, store=False, output_frame="base").json()["grasp_pose"]["position"]
    assert np.allclose([b["x"], b["y"], b["z"]], [-a["x"], -a["y"], a["z"]], atol=1e-12)


def test_bad_candidates_and_frames_are_422(api: TestClient) -> None:
    assert_problem(_plan(api, candidates=0), 422, "candidates")
    assert_problem(_plan(api, candidates=13), 422, "candidates")
    assert_problem(_plan(api, output_frame="tool9"), 422, "output_frame")
    assert_problem(_plan(api, output_frame="bad frame!"), 422, "output_frame")
