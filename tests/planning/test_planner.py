"""Top-grasp planning with strategies S and C: alignment, kinematics, reachability, collisions, branch choice."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.errors import InvalidInput
from softsig_service.geometry.quaternions import quat_to_matrix
from softsig_service.geometry.transforms import Pose
from softsig_service.objects import builtin_object
from softsig_service.planning.planner import GraspPlan, Planner, PlanRequest, planning_model
from softsig_service.planning.strategies import axis_angle_between_lines

ONE_DEGREE = math.radians(1.0)


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner()


def _check_kinematics(planner: Planner, plan: GraspPlan) -> None:
    assert plan.joint_positions is not None and plan.pre_grasp_joint_positions is not None
    assert plan.grasp_pose is not None and plan.pre_grasp_pose is not None
    for q, T in ((plan.joint_positions, plan.grasp_pose), (plan.pre_grasp_joint_positions, plan.pre_grasp_pose)):
        q_arr = np.asarray(q)
        assert planner.ur5.within_limits(q_arr)
        pos_err, rot_err = planner.ur5.pose_error(planner.ur5.fk(q_arr), T)
        assert pos_err <= 1e-5 and rot_err <= 1e-4


ARM_LIMITS = {"collision:table", "collision:self", "unreachable", "unreachable:lift", "unreachable:pre_grasp"}
"""Why a reachable-looking pose may still have no top grasp: the arm itself (its links against the table or each
other, its reach along the approach or the lift)."""


def _plans_or_meets_the_arm(hand: str, plan: GraspPlan) -> bool:
    """Whether ``plan`` succeeded; the SoftHand in line (its tool axis horizontal at a top grasp) may instead fail
    for the arm's own limits (8 of 300 random box poses with S, 3 with C: docs/planning.md), the bracket never."""
    if plan.success:
        return True
    assert hand == "pisa_iit_softhand" and set(plan.reasons) <= ARM_LIMITS, plan.reasons
    return False


@settings(max_examples=12, deadline=None)
@given(yaw=st.floats(-math.pi, math.pi), x=st.floats(0.35, 0.6), y=st.floats(-0.25, 0.25))
@pytest.mark.parametrize("hand", ["pisa_iit_softhand", "pisa_iit_softhand_bracket"])
def test_strategy_c_aligns_the_cs_and_s_aligns_the_box(
    planner: Planner, hand: str, yaw: float, x: float, y: float
) -> None:
    obj = builtin_object("box").with_pose(x, y, yaw)
    cs = planning_model(hand).signature
    plan_c = planner.plan(PlanRequest(hand=hand, obj=obj, strategy="C"))
    plan_s = planner.plan(PlanRequest(hand=hand, obj=obj, strategy="S"))
    if not (_plans_or_meets_the_arm(hand, plan_c) and _plans_or_meets_the_arm(hand, plan_s)):
        return
    assert plan_c.grasp_frame_pose is not None and plan_s.grasp_frame_pose is not None
    R_c, R_s = plan_c.grasp_frame_pose[:3, :3], plan_s.grasp_frame_pose[:3, :3]  # the CS is in the grasp frame
    assert axis_angle_between_lines(R_c @ cs.axis, obj.o2) <= ONE_DEGREE
    assert axis_angle_between_lines(R_s[:, 0], obj.o1) <= ONE_DEGREE
    assert R_c[2, 2] < -0.98 and R_s[2, 2] < -0.999  # top grasps: grasp +z down
    assert plan_c.quality["alignment_error"] <= ONE_DEGREE
    _check_kinematics(planner, plan_c)
    _check_kinematics(planner, plan_s)


@pytest.mark.parametrize("hand", ["pisa_iit_softhand", "sdm_hand", "rbo_hand2", "parallel_gripper"])
@pytest.mark.parametrize("obj_name", ["box", "apple", "cylinder"])
def test_every_hand_plans_every_builtin_object(planner: Planner, hand: str, obj_name: str) -> None:
    obj = builtin_object(obj_name).with_pose(0.5, 0.0, 0.3)
    for strategy in ("S", "C"):
        plan = planner.plan(PlanRequest(hand=hand, obj=obj, strategy=strategy))  # type: ignore[arg-type]
        assert plan.success, (hand, obj_name, strategy, plan.reasons)
        _check_kinematics(planner, plan)
        assert plan.quality["clearance"] is not None and plan.quality["clearance"] >= 0.004
        approach = np.asarray(plan.approach["direction"])
        assert approach[2] < -0.98
        assert plan.pre_grasp_pose is not None and plan.grasp_pose is not None
        rise = plan.pre_grasp_pose[:3, 3] - plan.grasp_pose[:3, 3]
        np.testing.assert_allclose(rise, -approach * plan.approach["desired_distance"], atol=1e-12)


def test_an_object_three_metres_away_is_unreachable(planner: Planner) -> None:
    obj = builtin_object("box").with_pose(3.0, 0.0, 0.0)
    for strategy in ("S", "C"):
        plan = planner.plan(PlanRequest(hand="parallel_gripper", obj=obj, strategy=strategy))  # type: ignore[arg-type]
        assert not plan.success
        assert plan.reasons == ["unreachable"]
        assert plan.joint_positions is None


def test_a_wrist_pose_forced_into_the_table_is_a_collision(planner: Planner) -> None:
    obj = builtin_object("box").with_pose(0.5, 0.1, 0.0)
    req = PlanRequest(hand="sdm_hand", obj=obj, strategy="S")
    plan = planner.plan(req)
    assert plan.success and plan.grasp_pose is not None
    assert planner.check_wrist_pose(req, plan.grasp_pose) == []
    sunk = plan.grasp_pose.copy()
    sunk[2, 3] -= 0.03  # 3 cm lower: the fingertips go through the table top
    sunk[0, 3] += 0.12  # beside the object, so only the table is in the way
    reasons = planner.check_wrist_pose(req, sunk)
    assert "collision:table" in reasons


def test_the_yaw_closer_to_the_current_configuration_wins(planner: Planner) -> None:
    obj = builtin_object("box").with_pose(0.5, 0.1, 0.2)
    first = planner.plan(PlanRequest(hand="parallel_gripper", obj=obj, strategy="S"))
    assert first.success and first.grasp_pose is not None and first.joint_positions is not None
    # the other branch: the same grasp turned by pi about the approach; start next to its IK solution
    other = first.grasp_pose.copy()
    other[:3, :2] *= -1.0
    ik = planner.ur5.solve_ik(other, np.asarray(first.joint_positions))
    assert ik.success
    second = planner.plan(PlanRequest(hand="parallel_gripper", obj=obj, strategy="S", current_q=tuple(ik.q)))
    assert second.success and second.grasp_pose is not None and second.joint_positions is not None
    x1, x2 = first.grasp_pose[:3, 0], second.grasp_pose[:3, 0]
    assert float(x1 @ x2) < -0.999  # the opposite yaw was chosen
    assert np.linalg.norm(np.asarray(second.joint_positions) - ik.q) < np.linalg.norm(
        np.asarray(first.joint_positions) - ik.q
    )


def test_plan_json_poses_round_trip_the_quaternion(planner: Planner) -> None:
    obj = builtin_object("cylinder").with_pose(0.45, -0.1, 1.0)
    plan = planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="C"))
    data = plan.to_json_dict()
    assert set(data) >= {
        "success", "reasons", "strategy", "hand", "object", "joint_names", "joint_positions",
        "pre_grasp_joint_positions", "grasp_pose", "pre_grasp_pose", "approach", "quality", "timing",
    }  # fmt: skip
    pose = data["grasp_pose"]
    assert pose["frame_id"] == "base_link" and set(pose["orientation"]) == {"x", "y", "z", "w"}
    back = Pose.from_wire(pose)
    assert plan.grasp_pose is not None
    np.testing.assert_allclose(quat_to_matrix(back.quaternion), plan.grasp_pose[:3, :3], atol=1e-12)
    np.testing.assert_allclose(back.position, plan.grasp_pose[:3, 3], atol=1e-12)
    assert set(data["quality"]) == {"alignment_error", "ik_residual", "clearance", "expected_capture"}


def test_bad_requests_name_the_field() -> None:
    obj = builtin_object("box")
    with pytest.raises(InvalidInput) as info:
        PlanRequest(hand="sdm_hand", obj=obj, strategy="X")  # type: ignore[arg-type]
    assert info.value.field == "strategy" and info.value.choices == ["C", "R", "S"]
    with pytest.raises(InvalidInput) as info:
        PlanRequest(hand="sdm_hand", obj=obj, strategy="S", approach_distance=float("nan"))
    assert info.value.field == "approach_distance"


def test_concurrent_plans_from_threads_match_sequential_ones(planner: Planner) -> None:
    """One planner serves several threads at once (the web service does), with no planner-wide lock: same answers,
    to the last bit, as one after the other. The solver's iterations and status are compared too: a CasADi solver
    shared between threads reports another call's statistics, and this test then fails."""
    import threading
    from concurrent.futures import ThreadPoolExecutor

    requests = [
        PlanRequest(hand=h, obj=builtin_object(o).with_pose(0.42 + 0.02 * k, -0.15 + 0.05 * k, 0.4 * k), strategy=s)
        for k in range(6)
        for h in ("pisa_iit_softhand", "parallel_gripper")
        for s in ("S", "C", "C")
        for o in ("box", "cylinder")
    ]  # type: ignore[arg-type]
    sequential = [planner.plan(r) for r in requests]
    # both of strategy C's paths run: the closed-form minimum (SoftHand) and the SQP (the gripper's table constraint)
    statuses = {p.solver["status"] for p in sequential if p.strategy == "C"}
    assert "closed_form" in statuses and statuses - {"closed_form"}, statuses
    threads = 8
    start = threading.Barrier(threads)

    def plan_all(offset: int) -> list[GraspPlan]:
        start.wait()  # every thread plans at the same time
        n = len(requests)
        return [planner.plan(requests[(offset + i) % n]) for i in range(n)]

    with ThreadPoolExecutor(max_workers=threads) as pool:
        results = list(pool.map(plan_all, range(0, threads * 5, 5)))
    n = len(requests)
    for offset, plans in zip(range(0, threads * 5, 5), results, strict=True):
        for i, b in enumerate(plans):
            a = sequential[(offset + i) % n]
            assert (a.success, a.reasons, a.solver) == (b.success, b.reasons, b.solver)
            assert a.joint_positions == b.joint_positions
            assert a.pre_grasp_joint_positions == b.pre_grasp_joint_positions
            assert np.array_equal(a.grasp_pose, b.grasp_pose)


# --- placement: one hand point over the object's centre for S and C ---------------------------------------


def _over_centre(plan: GraspPlan, point: np.ndarray, obj_center: np.ndarray) -> float:
    """Horizontal distance [m] between the grasp-frame ``point`` (a planning model's) at the grasp and the object's
    centre."""
    assert plan.grasp_frame_pose is not None
    world = plan.grasp_frame_pose[:3, :3] @ point + plan.grasp_frame_pose[:3, 3]
    return float(np.linalg.norm(world[:2] - obj_center[:2]))


@settings(max_examples=6, deadline=None)
@given(yaw=st.floats(-math.pi, math.pi), x=st.floats(0.4, 0.55), y=st.floats(-0.2, 0.2))
def test_s_and_c_put_the_same_hand_point_over_the_object_and_differ_in_yaw(
    planner: Planner, yaw: float, x: float, y: float
) -> None:
    obj = builtin_object("box").with_pose(x, y, yaw)
    model = planning_model("pisa_iit_softhand")
    assert model.knuckle is not None
    placements = (("open_centre", model.open_centre), ("grasp_centre", model.grasp_centre), ("knuckle", model.knuckle))
    for placement, point in placements:
        plans = {
            s: planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy=s, placement=placement))  # type: ignore[arg-type]
            for s in ("S", "C")
        }
        if not all(_plans_or_meets_the_arm("pisa_iit_softhand", plan) for plan in plans.values()):
            continue
        for s, plan in plans.items():
            assert _over_centre(plan, point, obj.center) <= 0.002, (s, placement)
            assert plan.solver["placement"] == placement
        # the yaws differ by the closure signature's tilt from the fingers' closing axis (hand y)
        cs = model.signature.axis
        tilt = axis_angle_between_lines(np.array([cs[0], cs[1], 0.0]), np.array([0.0, 1.0, 0.0]))
        R_s, R_c = (plans[s].grasp_frame_pose[:3, :3] for s in ("S", "C"))  # type: ignore[index]
        assert abs(axis_angle_between_lines(R_s[:, 0], R_c[:, 0]) - tilt) <= math.radians(1.5)


def test_the_default_placement_is_the_open_hand_centre_and_previous_keeps_the_old_rule(planner: Planner) -> None:
    obj = builtin_object("cylinder")
    model = planning_model("pisa_iit_softhand")
    assert np.allclose(model.open_centre, model.signature.anchor)  # c_0 is the ellipsoid CS's anchor
    assert model.grasp_centre[1] > model.open_centre[1] + 0.03  # c_T: pulled toward the wrist by the fist
    default = planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="S"))
    assert default.solver["placement"] == "open_centre"
    assert _over_centre(default, model.open_centre, obj.center) <= 0.002
    previous = planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="S", placement="previous"))
    assert _over_centre(previous, model.bbox_center, obj.center) <= 0.002
    with pytest.raises(InvalidInput) as info:
        PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="S", placement="middle")  # type: ignore[arg-type]
    assert info.value.field == "placement" and "open_centre" in (info.value.choices or ())


def test_the_knuckle_is_the_middle_finger_abduction_joint_on_the_palm_face() -> None:
    """The SoftHand's knuckle point, from the published palm-frame numbers independently of the MJCF: the middle
    finger's base (-3.3, 0, 100.699) mm projected along palm +x onto the palm face (palm x = 11.6 mm), with the
    palm frame at (-4.8, 50.95, 56.8) mm in the hand frame, palm +x = hand +z, +y = hand -x, +z = hand -y."""
    R = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # palm axes as columns, hand frame
    expected = (R @ np.array([11.6, 0.0, 100.699]) + np.array([-4.8, 50.95, 56.8])) / 1000.0
    knuckle = planning_model("pisa_iit_softhand").knuckle
    assert knuckle is not None and np.allclose(knuckle, expected, atol=1e-9)


def test_the_knuckle_placement_needs_a_declared_knuckle(planner: Planner) -> None:
    assert planning_model("parallel_gripper").knuckle is None
    with pytest.raises(InvalidInput) as info:
        planner.plan(PlanRequest(hand="parallel_gripper", obj=builtin_object("box"), strategy="S", placement="knuckle"))
    assert info.value.field == "placement" and "knuckle" in str(info.value)


def test_the_cs_criterion_reaches_the_plan(planner: Planner) -> None:
    obj = builtin_object("box")
    absolute = planning_model("pisa_iit_softhand").signature
    relative = planning_model("pisa_iit_softhand", "ellipsoid", None, "relative").signature
    assert abs(absolute.axis[2]) < 0.2 < 0.9 < abs(relative.axis[2])  # in the palm plane vs the palm normal
    plan = planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="C", cs_criterion="relative"))
    assert not plan.success and "alignment_impossible" in plan.reasons
    assert plan.solver["cs_criterion"] == "relative"


def test_the_approach_the_descent_cleared_is_clear_under_the_full_check(planner: Planner) -> None:
    """The planner leaves out the hand's pairs with table and object on the approach when its descent has shown
    them clear: every such approach, checked again with every pair, is collision-free."""
    rng = np.random.default_rng(5)
    skipped = 0
    for k in range(24):
        obj = builtin_object(("box", "apple", "cylinder")[k % 3]).with_pose(
            rng.uniform(0.35, 0.6), rng.uniform(-0.25, 0.25), rng.uniform(-math.pi, math.pi)
        )
        req = PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy=("S", "C")[k % 2])  # type: ignore[arg-type]
        plan = planner.plan(req)
        if not plan.success:
            continue
        model = planning_model(req.hand)
        world = planner._world(model, obj.table_height)
        world.set_object(obj.primitive(), obj.primitive_pose)
        q_pre, q = np.asarray(plan.pre_grasp_joint_positions), np.asarray(plan.joint_positions)
        path = q_pre + np.linspace(0.0, 1.0, 9)[:, None] * (q - q_pre)  # the approach, finer than planned
        report = world.check_waypoints(path, distances=True)
        assert not report.in_collision, (k, report.pairs)
        assert report.min_distance_hand_object is not None and report.min_distance_hand_object >= req.margin - 1e-4
        skipped += 1
    assert skipped >= 15
