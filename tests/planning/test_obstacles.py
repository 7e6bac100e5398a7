"""Obstacles on the table: the planner never plans through one. A box that blocks S's first yaw branch makes it
take the other; boxes on both sides make it fail naming them; a far one changes nothing; every plan it returns is
clear of its obstacles when checked afresh (a new collision world holding the obstacle, at the plan's joints)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softsig_service.arm.collision import CollisionWorld
from softsig_service.geometry.transforms import yaw_of
from softsig_service.objects import TableObject, box, builtin_object
from softsig_service.planning.hand_model import planning_model
from softsig_service.planning.planner import Planner
from softsig_service.planning.request import GraspPlan, PlanRequest

TARGET = builtin_object("box", x=0.5, y=0.0, yaw=0.0)


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner()


def _post(y: float, x: float = 0.5) -> TableObject:
    """A 10 x 4 x 12 cm block standing on the table at (x, y)."""
    return box((0.10, 0.04, 0.12), 0.5, x=x, y=y, yaw=0.0)


def _plan(planner: Planner, hand: str, *obstacles: TableObject) -> GraspPlan:
    return planner.plan(PlanRequest(hand=hand, obj=TARGET, strategy="S", obstacles=obstacles))


def _clear(planner: Planner, hand: str, plan: GraspPlan, obstacle: TableObject) -> bool:
    """Whether the arm and hand at the plan's pre-grasp, grasp and 20 joint-space steps between stay clear of
    ``obstacle``, checked in a world of their own."""
    world = CollisionWorld(planner.ur5, planning_model(hand, "ellipsoid").shapes)
    world.set_object(obstacle.primitive(), obstacle.primitive_pose)
    assert plan.pre_grasp_joint_positions is not None and plan.joint_positions is not None
    report = world.check_path(plan.pre_grasp_joint_positions, plan.joint_positions, steps=20, check_table=False,
                              check_self=False, distances=False, stop_at_first=True)  # fmt: skip
    return not report.in_collision


def test_a_block_on_one_side_makes_s_take_its_other_branch(planner: Planner) -> None:
    free = _plan(planner, "pisa_iit_softhand")
    assert free.success
    block = _post(0.12 if abs(yaw_of(free.grasp_frame_pose[:3, :3])) > 1.0 else -0.12)
    blocked = _plan(planner, "pisa_iit_softhand", block)
    assert blocked.success, blocked.reasons
    turn = abs(yaw_of(blocked.grasp_frame_pose[:3, :3]) - yaw_of(free.grasp_frame_pose[:3, :3]))
    assert math.isclose(turn, math.pi, abs_tol=1e-6)  # the other yaw branch: thumb and fingers swapped
    assert not _clear(planner, "pisa_iit_softhand", free, block)  # the first branch went through it
    assert _clear(planner, "pisa_iit_softhand", blocked, block)


@pytest.mark.parametrize("hand", ["pisa_iit_softhand", "parallel_gripper"])
def test_blocks_on_both_sides_fail_naming_them(planner: Planner, hand: str) -> None:
    plan = _plan(planner, hand, _post(-0.06), _post(0.6), _post(0.06))
    assert not plan.success
    assert set(plan.reasons) <= {"collision:obstacle[0]", "collision:obstacle[2]"} and plan.reasons, plan.reasons


def test_a_far_obstacle_changes_nothing(planner: Planner) -> None:
    free = _plan(planner, "parallel_gripper")
    far = _plan(planner, "parallel_gripper", _post(0.6), _post(-0.5, x=0.9))
    assert far.success and np.array_equal(far.grasp_pose, free.grasp_pose)


@pytest.mark.parametrize("seed", range(6))
def test_every_plan_is_clear_of_its_obstacle(planner: Planner, seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(4):
        side = rng.choice([-1.0, 1.0])
        obstacle = box((rng.uniform(0.03, 0.12), rng.uniform(0.03, 0.08), rng.uniform(0.05, 0.2)), 0.3,
                       x=0.5 + rng.uniform(-0.1, 0.1), y=side * rng.uniform(0.07, 0.2), yaw=rng.uniform(-3, 3))  # fmt: skip
        for hand in ("pisa_iit_softhand", "parallel_gripper"):
            plan = _plan(planner, hand, obstacle)
            if plan.success:
                assert _clear(planner, hand, plan, obstacle)
            else:
                assert "collision:obstacle[0]" in plan.reasons or "unreachable" in plan.reasons[0], plan.reasons
