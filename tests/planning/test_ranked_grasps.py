"""Ranked grasps: one grasp by default (today's plan), k distinct grasps best first on request, each passing the
planner's own checks again from its pose alone; the quality models; the answer in any frame turning back to the
same base_link poses; the trajectories on the stated line through an independent FK, within the joint limits, and
the very joint paths the validation executes."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.arm.trajectory import ACCELERATION_LIMIT, arm_paths, path_deviation
from softsig_service.errors import InvalidInput
from softsig_service.experiments.trial import default_planner
from softsig_service.geometry.transforms import Pose, rot_x, rot_y, rot_z
from softsig_service.objects import box, builtin_object
from softsig_service.objects.frames import output_frame_pose
from softsig_service.planning.hand_model import planning_model
from softsig_service.planning.ranking import geometric_quality, relative_pose_of
from softsig_service.planning.request import PlanRequest
from softsig_service.planning.strategies import relative_poses
from softsig_service.signatures.capture import wrap_theta

BOX = builtin_object("box")


def _plan(**kw: object) -> object:
    fields = {"hand": "pisa_iit_softhand", "obj": BOX, "strategy": "C", **kw}
    return default_planner().plan(PlanRequest(**fields))  # type: ignore[arg-type]


def test_one_candidate_is_today_s_plan_and_its_first_grasp() -> None:
    plan = _plan()
    assert plan.success and len(plan.grasps) == 1  # type: ignore[attr-defined]
    g = plan.grasps[0]  # type: ignore[attr-defined]
    assert g["rank"] == 1 and g["primary"] and np.array_equal(g["grasp_pose"], plan.grasp_pose)  # type: ignore[attr-defined]
    assert g["joint_positions"] == plan.joint_positions  # type: ignore[attr-defined]


@pytest.mark.parametrize(("hand", "strategy"), [("pisa_iit_softhand", "C"), ("pisa_iit_softhand", "S"),
                                                ("rbo_hand2", "C"), ("parallel_gripper", "S")])  # fmt: skip
def test_k_grasps_are_distinct_ranked_and_each_passes_the_checks_alone(hand: str, strategy: str) -> None:
    planner = default_planner()
    req = PlanRequest(hand=hand, obj=BOX, strategy=strategy, candidates=6)  # type: ignore[arg-type]
    plan = planner.plan(req)
    grasps = plan.grasps
    assert plan.success and len(grasps) == 6
    assert [g["rank"] for g in grasps] == [1, 2, 3, 4, 5, 6]
    qualities = [g["grasp_quality"] for g in grasps]
    assert all(a >= b - 1e-9 for a, b in itertools.pairwise(qualities))  # best first (ties: 1e-9)
    assert all(0.0 <= q <= 1.0 for q in qualities)
    assert np.array_equal(grasps[0]["grasp_pose"], plan.grasp_pose)  # the top-level fields describe the first
    for i, g in enumerate(grasps):
        assert planner.check_wrist_pose(req, g["grasp_pose"]) == [], g["label"]
        for other in grasps[i + 1 :]:
            assert np.linalg.norm(g["grasp_pose"][:3, 3] - other["grasp_pose"][:3, 3]) > 1e-3 or not np.allclose(
                g["grasp_pose"][:3, :3], other["grasp_pose"][:3, :3], atol=1e-3
            )


def test_an_obstacle_removes_the_grasps_it_blocks_and_names_no_ranked_one() -> None:
    planner = default_planner()
    post = box((0.04, 0.04, 0.14), 0.3, x=0.5, y=0.09, yaw=0.0)
    free = planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=BOX, strategy="C", candidates=12))
    req = PlanRequest(hand="pisa_iit_softhand", obj=BOX, strategy="C", candidates=12, obstacles=(post,))
    blocked = planner.plan(req)
    assert 0 < len(blocked.grasps) < len(free.grasps)
    for g in blocked.grasps:
        assert planner.check_wrist_pose(req, g["grasp_pose"]) == []


def test_quality_comes_from_the_capture_model_when_there_is_one() -> None:
    from softsig_service.cli.options import read_capture

    capture = read_capture(None, hand="pisa_iit_softhand", obj=BOX)
    assert capture is not None
    plan = _plan(candidates=4, capture=capture)
    model = planning_model("pisa_iit_softhand", "ellipsoid")
    point = model.placement_point("R", "open_centre")
    for g in plan.grasps:  # type: ignore[attr-defined]
        assert g["quality_model"] == "capture"
        theta, u, v = relative_pose_of(g["grasp_frame_pose"], point, BOX)
        assert g["grasp_quality"] == pytest.approx(float(capture.probability(theta, u, v)), abs=1e-12)
    geometric = _plan(candidates=4)
    assert {g["quality_model"] for g in geometric.grasps} == {"geometric"}  # type: ignore[attr-defined]


@settings(max_examples=60, deadline=None)
@given(theta=st.floats(-1.5, 1.5), u=st.floats(-0.05, 0.05), v=st.floats(-0.05, 0.05), yaw=st.floats(-3.0, 3.0),
       x=st.floats(0.3, 0.6), y=st.floats(-0.3, 0.3))  # fmt: skip
def test_relative_pose_of_inverts_relative_poses(
    theta: float, u: float, v: float, yaw: float, x: float, y: float
) -> None:
    obj = builtin_object("box", x=x, y=y, yaw=yaw)
    hand_point = np.array([0.01, -0.02, 0.09])
    for T in relative_poses(obj.center, obj.o1, hand_point, theta, u, v):
        t, uu, vv = relative_pose_of(T, hand_point, obj)
        assert abs(float(wrap_theta(t - theta))) < 1e-9 and uu == pytest.approx(u, abs=1e-9)
        assert vv == pytest.approx(v, abs=1e-9)


def test_the_geometric_quality_is_one_for_a_centred_grasp_closing_across_and_falls_off() -> None:
    cs = np.array([0.0, 1.0, 0.0])  # closes along hand +y
    point = np.zeros(3)
    across, along = (relative_poses(BOX.center, BOX.o1, point, th, 0.0, 0.0)[0] for th in (0.0, math.pi / 2))
    assert geometric_quality(across, cs, point, BOX) == pytest.approx(1.0)  # hand +x along o1: +y across it
    assert geometric_quality(along, cs, point, BOX) == pytest.approx(0.0, abs=1e-12)
    shifted = relative_poses(BOX.center, BOX.o1, point, 0.0, 0.04, 0.0)[0]  # 4 cm = a quarter of 0.16 m
    assert geometric_quality(shifted, cs, point, BOX) == pytest.approx(math.exp(-0.5), rel=1e-9)


def test_every_output_frame_turns_back_to_the_same_base_link_poses() -> None:
    plan = _plan(candidates=3)
    camera = np.eye(4)
    camera[:3, :3] = rot_z(0.7) @ rot_y(-0.3) @ rot_x(2.1)
    camera[:3, 3] = [0.5, -0.45, 0.55]
    base = plan.to_json_dict()  # type: ignore[attr-defined]
    for name, frames in (
        ("base", None),
        ("object", None),
        ("camera_color_optical_frame", {"camera_color_optical_frame": camera}),
    ):
        T = output_frame_pose(name, frames, BOX.pose)
        data = plan.to_json_dict(name, T)  # type: ignore[attr-defined]
        assert data["output_frame"] == name and data["grasp_pose"]["frame_id"] == name
        for g_out, g_base in zip(data["grasps"], base["grasps"], strict=True):
            for key in ("grasp_pose", "pre_grasp_pose"):
                back = T @ Pose.from_wire(g_out[key]).matrix()
                assert np.allclose(back, Pose.from_wire(g_base[key]).matrix(), atol=1e-9)
            msg = g_out["moveit_grasp"]
            assert msg["grasp_pose"]["header"]["frame_id"] == name
            v = msg["pre_grasp_approach"]["direction"]["vector"]
            assert np.allclose(T[:3, :3] @ [v["x"], v["y"], v["z"]], [0.0, 0.0, -1.0], atol=1e-9)
    assert np.allclose(output_frame_pose("base", None, BOX.pose)[:3, :3], np.diag([-1.0, -1.0, 1.0]))
    with pytest.raises(InvalidInput) as err:
        output_frame_pose("tool9", None, BOX.pose)
    assert err.value.field == "output_frame" and "base" in err.value.choices


def test_the_trajectories_follow_the_line_within_the_limits_and_are_what_the_validation_runs() -> None:
    from softsig_service.simulation.scene import build_scene

    planner = default_planner()
    plan = planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=BOX, strategy="C", candidates=3))
    scene = build_scene("pisa_iit_softhand", BOX)

    def mujoco_fk(q: np.ndarray) -> np.ndarray:  # an FK independent of Pinocchio's: MuJoCo's of the same URDF
        return scene.flange_pose(scene.make_data(q, BOX.primitive_pose))

    for g in plan.grasps:
        approach, lift = g["approach_trajectory"], g["retreat_trajectory"]
        A, L = np.array(approach["positions"]), np.array(lift["positions"])
        T_top = g["grasp_pose"].copy()
        T_top[2, 3] += 0.15
        assert path_deviation(mujoco_fk, A, g["pre_grasp_pose"], g["grasp_pose"], samples=60) < 1e-3
        assert path_deviation(mujoco_fk, L, g["grasp_pose"], T_top, samples=60) < 1e-3
        for traj in (approach, lift):
            t = np.array(traj["time_from_start"])
            V = np.array(traj["velocities"])
            assert t[0] == 0.0 and np.all(np.diff(t) > 0) and t[-1] == pytest.approx(traj["duration"])
            assert np.allclose(V[0], 0.0) and np.allclose(V[-1], 0.0)
            assert np.all(np.abs(V) <= planner.ur5.velocity_limit)
            dt = np.diff(t)[:, None]
            assert np.all(np.abs(np.diff(V, axis=0) / dt) <= ACCELERATION_LIMIT)
        # the validation's paths from the plan's poses are these (one source: arm/trajectory.py)
        paths = arm_paths(planner.ur5, g["pre_grasp_pose"], g["grasp_pose"], np.array(g["pre_grasp_joint_positions"]))
        assert not isinstance(paths, str)
        assert np.array_equal(paths[0], A) and np.array_equal(paths[1], L)
        assert np.allclose(A[-1], g["joint_positions"], atol=0.0)


def test_candidates_out_of_range_are_refused() -> None:
    for bad in (0, 13, True, 2.0):
        with pytest.raises(InvalidInput) as err:
            PlanRequest(hand="pisa_iit_softhand", obj=BOX, strategy="C", candidates=bad)  # type: ignore[arg-type]
        assert err.value.field == "candidates"


def test_the_old_placement_name_is_the_new_one() -> None:
    old = _plan(strategy="S", placement="previous")
    new = _plan(strategy="S", placement="per_strategy")
    assert old.solver["placement"] == new.solver["placement"] == "per_strategy"  # type: ignore[attr-defined]
    assert np.array_equal(old.grasp_pose, new.grasp_pose)  # type: ignore[attr-defined]
