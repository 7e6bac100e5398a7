"""The SoftHand on its two mounts: in line with the tool axis through an ATI Gamma F/T sensor (``pisa_iit_softhand``,
the paper's setup) and on a side bracket (``pisa_iit_softhand_bracket``). The hand is the same in its grasp frame;
only where it sits on the flange differs."""

from __future__ import annotations

import numpy as np
import pytest

from softsig_service.experiments.trial import default_planner
from softsig_service.hands.model import load_hand
from softsig_service.objects import builtin_object
from softsig_service.planning.hand_model import planning_model
from softsig_service.planning.request import PlanRequest
from softsig_service.simulation.scene import build_scene

INLINE = "pisa_iit_softhand"
BRACKET = "pisa_iit_softhand_bracket"


def test_the_hand_is_the_same_in_its_grasp_frame_on_both_mounts() -> None:
    bracket, inline = planning_model(BRACKET), planning_model(INLINE)
    assert bracket.point_names == inline.point_names
    assert np.allclose(bracket.points_open, inline.points_open, atol=1e-12)
    assert np.allclose(bracket.signature.axis, inline.signature.axis, atol=1e-9)
    assert bracket.knuckle is not None and inline.knuckle is not None
    assert np.allclose(bracket.knuckle, inline.knuckle, atol=1e-12)
    hand_shapes = [s for s in inline.shapes if "sensor" not in s.name and "bracket" not in s.name]
    assert len(hand_shapes) == len([s for s in bracket.shapes if "bracket" not in s.name])


def test_in_line_the_fingers_run_along_the_tool_axis_behind_the_sensor() -> None:
    hand = load_hand(INLINE)
    T_HG = hand.grasp_frame
    # grasp frame -y (along the fingers) is the flange's +z; its +z (out of the palm) is horizontal to the flange
    assert np.allclose(T_HG[:3, :3] @ np.array([0.0, -1.0, 0.0]), [0.0, 0.0, 1.0], atol=1e-12)
    assert abs((T_HG[:3, :3] @ np.array([0.0, 0.0, 1.0]))[2]) < 1e-12
    sensor = hand.model.geom("sensor_geom")
    radius, half = sensor.size[0], sensor.size[1]
    assert np.isclose(2 * radius, 0.0754) and np.isclose(2 * half, 0.0333) and np.isclose(sensor.pos[2], half)
    bracket = load_hand(BRACKET)
    assert np.isclose(hand.model.body_mass.sum() - bracket.model.body_mass.sum(), 0.255 - 0.12)


@pytest.mark.parametrize("strategy", ["S", "C"])
def test_the_same_grasp_frame_plan_reached_with_the_tool_axis_horizontal(strategy: str) -> None:
    box = builtin_object("box")
    planner = default_planner()
    a = planner.plan(PlanRequest(hand=BRACKET, obj=box, strategy=strategy))  # type: ignore[arg-type]
    b = planner.plan(PlanRequest(hand=INLINE, obj=box, strategy=strategy))  # type: ignore[arg-type]
    assert a.success and b.success, (a.reasons, b.reasons)
    assert a.grasp_frame_pose is not None and b.grasp_frame_pose is not None and b.grasp_pose is not None
    # the grasp frame's pose is the bracket plan's, or its half-turn about the vertical through the object's centre
    # (the other yaw branch: each plan takes the one nearest its arm)
    half_turn = np.diag([-1.0, -1.0, 1.0, 1.0])
    half_turn[:2, 3] = 2 * box.center[:2]
    assert any(np.allclose(T @ a.grasp_frame_pose, b.grasp_frame_pose, atol=1e-4) for T in (np.eye(4), half_turn))
    assert abs(b.grasp_pose[2, 2]) < 1e-6  # the flange's tool axis is horizontal in line ...
    assert a.grasp_pose is not None and abs(a.grasp_pose[2, 2] + 1.0) < 1e-6  # ... and points down on the bracket
    scene = build_scene(INLINE, box)
    data = scene.make_data(np.array(b.joint_positions), box.primitive_pose)
    assert np.allclose(scene.flange_pose(data), b.grasp_pose, atol=1e-5)  # MuJoCo's forward kinematics agrees
