"""Strategy C's NLP over the arm's joints: its symbolic FK is Pinocchio's; an upright object keeps the closed form's
pose; a box tilted 20 degrees about its long axis gets a wrist tilted with it; a box at the workspace's edge, where
the closed form's reach model gives up, gets a plan the validation carries; at the answer the NLP's constraints
hold, checked with Pinocchio's and MuJoCo's kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.arm.ur5 import load_ur5
from softsig_service.errors import InvalidInput
from softsig_service.experiments.trial import default_planner, run_trial
from softsig_service.objects import builtin_object, object_from_json
from softsig_service.planning.arm_fk import symbolic_fk
from softsig_service.planning.hand_model import planning_model
from softsig_service.planning.request import PlanRequest
from softsig_service.planning.wrist_nlp import CENTRED, DEFAULT_CONE, LIMIT_MARGIN, solve_joint_wrist
from softsig_service.simulation.scene import build_scene

HAND = "pisa_iit_softhand_bracket"
"""The NLP's cases were chosen on the bracket mount (tool axis vertical at a top grasp): there the 20-degree box and
the 0.9 m reach need the joint NLP; in line the same box's untilted pose already meets the constraints."""


def _tilted_box(angle: float) -> object:
    q = {"x": math.sin(angle / 2), "y": 0.0, "z": 0.0, "w": math.cos(angle / 2)}  # about the box's long axis
    return object_from_json({"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15,
                             "pose": {"x": 0.5, "y": 0.0, "orientation": q}})  # fmt: skip


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6))
def test_the_symbolic_fk_is_pinocchio_s(q: list[float]) -> None:
    ur5 = load_ur5()
    assert np.allclose(np.array(symbolic_fk(ur5)(q)), ur5.fk(np.array(q)), atol=1e-12)


def test_an_upright_object_keeps_the_closed_form_pose() -> None:
    for name in ("box", "apple", "cylinder"):
        plan = default_planner().plan(PlanRequest(hand=HAND, obj=builtin_object(name), strategy="C"))
        assert plan.success and plan.solver["status"] == "closed_form"
        assert plan.grasp_frame_pose[2, 2] == pytest.approx(-1.0, abs=1e-12)  # straight down


def test_a_tilted_box_gets_a_wrist_tilted_with_it() -> None:
    box = _tilted_box(math.radians(20.0))
    plan = default_planner().plan(PlanRequest(hand=HAND, obj=box, strategy="C"))  # type: ignore[arg-type]
    assert plan.success and plan.solver["status"].startswith("joint_nlp")
    T = plan.grasp_frame_pose
    up = box.own_axes[:, 2]  # type: ignore[attr-defined]
    assert math.degrees(math.acos(-T[2, 2])) == pytest.approx(20.0, abs=0.2)
    assert T[:3, 2] @ -up > math.cos(math.radians(0.5))  # along the box's own down axis
    scene = build_scene(HAND, box)  # type: ignore[arg-type]
    data = scene.make_data(np.array(plan.joint_positions), box.primitive_pose)  # type: ignore[attr-defined]
    assert np.allclose(scene.flange_pose(data), plan.grasp_pose, atol=1e-5)  # MuJoCo's FK of the joints
    straight = default_planner().plan(PlanRequest(hand=HAND, obj=box, strategy="C", approach_cone=0.0))  # type: ignore[arg-type]
    assert straight.grasp_frame_pose[2, 2] == pytest.approx(-1.0, abs=1e-9)  # no cone: straight down


def test_the_edge_of_the_workspace_is_planned_and_carried() -> None:
    box = builtin_object("box", x=0.9)
    planner = default_planner()
    plan = planner.plan(PlanRequest(hand=HAND, obj=box, strategy="C"))
    assert plan.success and plan.solver["status"].startswith("joint_nlp"), plan.reasons
    assert run_trial(HAND, box, "C", seed=0, plan=plan).success
    far = planner.plan(PlanRequest(hand=HAND, obj=builtin_object("box", x=1.0), strategy="C"))
    assert not far.success and far.reasons  # beyond the arm's reach it says why


def test_at_the_answer_the_constraints_hold() -> None:
    ur5 = load_ur5()
    model = planning_model(HAND)
    box = _tilted_box(math.radians(15.0))
    up, minor = box.own_axes[:, 2], box.own_axes[:, 1]  # type: ignore[attr-defined]
    point = model.placement_point("C", "open_centre")
    sol = solve_joint_wrist(ur5, np.zeros(6), model.grasp_in_flange, model.signature.axis, point,
                            model.points_open, box.center, minor, up, 0.0, 0.005, stand_off=0.04)  # type: ignore[attr-defined]  # fmt: skip
    assert sol.success
    T = ur5.fk(sol.q) @ model.grasp_in_flange  # Pinocchio's FK, not the NLP's
    assert np.allclose(T, sol.T_world_grasp, atol=1e-9)
    assert -T[2, 2] >= math.cos(DEFAULT_CONE) - 1e-9
    heights = (model.points_open @ T[:3, :3].T + T[:3, 3])[:, 2]
    assert heights.min() >= 0.005 - 1e-6
    assert np.all(sol.q >= ur5.lower + LIMIT_MARGIN - 1e-9) and np.all(sol.q <= ur5.upper - LIMIT_MARGIN + 1e-9)
    d = T[:3, :3] @ point + T[:3, 3] - box.center  # type: ignore[attr-defined]
    assert np.linalg.norm(d - (d @ T[:3, 2]) * T[:3, 2]) <= CENTRED
    w = T[:3, :3] @ model.signature.axis
    w -= (w @ up) * up
    assert abs(w @ minor) / np.linalg.norm(w) > math.cos(1e-3)


def test_the_cone_is_bounded_and_the_cli_default_is_the_planner_s() -> None:
    import inspect

    from softsig_service.cli.main import plan as cli_plan

    assert inspect.signature(cli_plan).parameters["approach_cone"].default == DEFAULT_CONE
    with pytest.raises(InvalidInput) as err:
        PlanRequest(hand=HAND, obj=builtin_object("box"), strategy="C", approach_cone=2.0)
    assert err.value.field == "approach_cone"
