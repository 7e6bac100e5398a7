"""Strategy R: its choice of relative pose, its poses, and its plans through the planner's checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.errors import InvalidInput
from softsig_service.objects import builtin_object
from softsig_service.planning.planner import Planner, PlanRequest, planning_model
from softsig_service.planning.strategies import relative_poses, strategy_s_poses
from softsig_service.planning.strategy_r import c_relative_theta, solve_strategy_r
from softsig_service.signatures.capture import CaptureModel, theta_axis, uniform_axis, wrap_theta

TH = theta_axis(24)
U = uniform_axis(0.03, 0.005)


def box_region(theta0: float, u0: float, v0: float, half_theta: float, half_uv: float) -> CaptureModel:
    """1 inside a box of relative poses centred at (theta0, u0, v0) (symmetric about it), 0 outside."""
    T, Uu, V = np.meshgrid(TH, U, U, indexing="ij")
    inside = (np.abs(wrap_theta(T - theta0)) <= half_theta + 1e-9) & (np.abs(Uu - u0) <= half_uv + 1e-9)
    inside &= np.abs(V - v0) <= half_uv + 1e-9
    return CaptureModel(TH, U, U, inside.astype(float))


@settings(max_examples=15, deadline=None)
@given(st.sampled_from(list(TH)))
def test_without_noise_and_with_a_region_symmetric_about_c_r_is_c(theta_c: float) -> None:
    model = box_region(theta_c, 0.0, 0.0, 0.4, 0.01)
    choice = solve_strategy_r(model, 0.0, 0.0, theta_c)
    assert (choice.theta, choice.u, choice.v) == pytest.approx((float(wrap_theta(theta_c)), 0.0, 0.0), abs=1e-12)
    assert choice.expected == pytest.approx(1.0)


@pytest.mark.parametrize(("sigma_r", "sigma_t"), [(0.1, 0.01), (0.2, 0.02)])
def test_under_noise_r_centres_the_capture_region(sigma_r: float, sigma_t: float) -> None:
    theta0, u0, v0 = TH[16], 0.01, -0.005  # a region away from C's pose (theta_C = 0)
    model = box_region(theta0, u0, v0, 0.4, 0.012)
    choice = solve_strategy_r(model, sigma_r, sigma_t, theta_c=0.0)
    assert abs(float(wrap_theta(choice.theta - theta0))) <= math.pi / len(TH) + 1e-9, choice
    assert abs(choice.u - u0) <= 0.0025 + 1e-9 and abs(choice.v - v0) <= 0.0025 + 1e-9, choice
    at_c = float(model.expected(0.0, 0.0, 0.0, sigma_r, sigma_t))
    assert choice.expected > at_c, "R is worth more than C's pose here"
    # and no pose of a fine grid does better by more than the pull toward C
    T, Uu, V = np.meshgrid(np.linspace(-1.5, 1.5, 61), np.linspace(-0.03, 0.03, 13), np.linspace(-0.03, 0.03, 13))
    assert model.expected(T, Uu, V, sigma_r, sigma_t).max() <= choice.expected + 0.02


@settings(max_examples=30, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(-1, 1), st.floats(-1, 1), st.floats(-0.3, 0.3))
def test_c_relative_theta_puts_the_cs_across_the_object(yaw: float, cx: float, cy: float, cz: float) -> None:
    cs = np.array([cx, cy, cz])
    if np.linalg.norm(cs[:2]) < 0.1:
        return
    o1 = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    for T in relative_poses(np.array([0.5, 0.0, 0.05]), o1, np.zeros(3), c_relative_theta(cs), 0.0, 0.0):
        w = T[:3, :3] @ cs
        assert abs(float(w[:2] @ o1[:2])) <= 1e-9 * (1 + np.linalg.norm(w)), "the CS lies along o2"


@settings(max_examples=30, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(-0.5, 0.5), st.floats(-0.05, 0.05), st.floats(-0.05, 0.05))
def test_relative_poses_place_the_object_where_asked(yaw: float, theta: float, u: float, v: float) -> None:
    c = np.array([0.45, 0.1, 0.03])
    o1 = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    point = np.array([-0.026, -0.059, 0.057])
    for T in relative_poses(c, o1, point, theta, u, v):
        R = T[:3, :3]
        placed = T[:3, :3] @ point + T[:3, 3]
        offset = c - placed
        assert R[:, 2] @ [0, 0, -1] == pytest.approx(1.0), "a top grasp"
        assert offset[:2] @ R[:2, 0] == pytest.approx(u, abs=1e-12) and offset[:2] @ R[:2, 1] == pytest.approx(v)
        hand_x = math.atan2(R[1, 0], R[0, 0])
        assert float(wrap_theta(yaw - hand_x - theta)) == pytest.approx(0.0, abs=1e-9)
    s_poses = strategy_s_poses(c, o1, point)
    assert len(s_poses) == 2
    for T in s_poses:  # S, the relative pose (0, 0, 0): hand x along the major axis, the point over the centre
        assert abs(T[:3, 0] @ o1) == pytest.approx(1.0, abs=1e-12)
        assert np.allclose((T[:3, :3] @ point + T[:3, 3])[:2], c[:2], atol=1e-12)


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner()


def _yaw(T: np.ndarray) -> float:
    return math.atan2(T[1, 0], T[0, 0])


def test_r_plans_like_c_without_noise_and_respects_every_check(planner: Planner) -> None:
    hand = "pisa_iit_softhand"
    theta_c = c_relative_theta(planning_model(hand).signature.axis)
    model = box_region(theta_c, 0.0, 0.0, 0.5, 0.015)
    obj = builtin_object("box", x=0.5, y=0.05, yaw=0.4)
    c_plan = planner.plan(PlanRequest(hand=hand, obj=obj, strategy="C"))
    r_plan = planner.plan(PlanRequest(hand=hand, obj=obj, strategy="R", capture=model))
    assert c_plan.success and r_plan.success, (c_plan.reasons, r_plan.reasons)
    assert c_plan.grasp_pose is not None and r_plan.grasp_pose is not None
    d_yaw = math.remainder(_yaw(r_plan.grasp_pose) - _yaw(c_plan.grasp_pose), math.pi)
    assert abs(d_yaw) < 2e-3, "the same yaw as C (up to the half turn)"
    assert r_plan.quality["alignment_error"] is not None and r_plan.quality["alignment_error"] < 2e-3
    assert r_plan.quality["expected_capture"] == pytest.approx(1.0)
    # with noise and the region moved off C's pose, R still passes every check the planner makes
    moved = box_region(theta_c + 0.5, 0.01, 0.0, 0.4, 0.015)
    noisy = planner.plan(PlanRequest(hand=hand, obj=obj, strategy="R", capture=moved, sigma_r=0.2, sigma_t=0.02))
    assert noisy.success, noisy.reasons
    assert noisy.joint_positions is not None and noisy.quality["clearance"] is not None
    assert noisy.quality["clearance"] >= -1e-9 and noisy.quality["ik_residual"] is not None
    assert noisy.quality["ik_residual"] < 1e-6
    limits = planner.ur5.model.lowerPositionLimit, planner.ur5.model.upperPositionLimit
    q = np.asarray(noisy.joint_positions)
    assert np.all(q >= limits[0] - 1e-9) and np.all(q <= limits[1] + 1e-9)
    assert abs(math.remainder(_yaw(noisy.grasp_pose) - _yaw(c_plan.grasp_pose), math.pi)) > 0.3, "R moved"


def test_r_needs_a_capture_model_and_sane_sigmas() -> None:
    obj = builtin_object("box")
    with pytest.raises(InvalidInput) as info:
        PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="R")
    assert info.value.field == "capture"
    with pytest.raises(InvalidInput) as info:
        PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="S", sigma_r=-0.1)
    assert info.value.field == "sigma_r"


def test_r_from_many_threads_matches_sequential_choices() -> None:
    """Each thread solves with its own CasADi solver (its stats are those of its own last call)."""
    from concurrent.futures import ThreadPoolExecutor

    model = box_region(TH[16], 0.01, -0.005, 0.4, 0.012)
    cases = [(sr, st, tc) for sr, st in ((0.1, 0.01), (0.2, 0.02)) for tc in (0.0, 0.3, -0.6)] * 4
    sequential = [solve_strategy_r(model, *c) for c in cases]
    with ThreadPoolExecutor(max_workers=6) as pool:
        parallel = list(pool.map(lambda c: solve_strategy_r(model, *c), cases))
    assert parallel == sequential
