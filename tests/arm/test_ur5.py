"""UR5 model, forward kinematics against the published DH parameters, and numeric IK."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from softsig_service.arm.robots_dir import find_robots_dir
from softsig_service.arm.ur5 import HOME_Q, JOINT_NAMES, UR5, load_ur5
from softsig_service.config import Settings, default_settings
from softsig_service.errors import InvalidInput
from softsig_service.geometry.transforms import make_transform, rot_x, rot_z

# UR5: standard DH parameters [m] (Universal Robots, UR5 DH table)
D1, A2, A3, D4, D5, D6 = 0.089159, 0.425, 0.39225, 0.10915, 0.09465, 0.0823


def dh_flange(q: np.ndarray) -> np.ndarray:
    """Flange pose from the standard UR5 DH table (base frame of the DH convention)."""
    a = [0.0, -A2, -A3, 0.0, 0.0, 0.0]
    d = [D1, 0.0, 0.0, D4, D5, D6]
    alpha = [math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0]
    T = np.eye(4)
    for i in range(6):
        ct, st = math.cos(q[i]), math.sin(q[i])
        ca, sa = math.cos(alpha[i]), math.sin(alpha[i])
        T = T @ np.array(
            [
                [ct, -st * ca, st * sa, a[i] * ct],
                [st, ct * ca, -ct * sa, a[i] * st],
                [0, sa, ca, d[i]],
                [0, 0, 0, 1],
            ]
        )
    return T


@pytest.fixture(scope="module")
def ur5() -> UR5:
    return load_ur5()


def test_model_is_cached_and_has_the_ur5_joints(ur5: UR5) -> None:
    assert load_ur5() is ur5
    assert ur5.joint_names == JOINT_NAMES
    assert ur5.nq == 6
    assert np.allclose(ur5.upper, [2 * math.pi, 2 * math.pi, math.pi, 2 * math.pi, 2 * math.pi, 2 * math.pi])
    assert np.allclose(ur5.lower, -ur5.upper)
    assert np.allclose(ur5.effort_limit, [150, 150, 150, 28, 28, 28])
    assert ur5.urdf_path.name == "ur5_robot.urdf" and ur5.urdf_path.is_file()
    assert ur5.srdf_path.is_file()


def test_robots_dir_override_comes_from_the_settings(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    found = find_robots_dir()
    assert (found / "ur_description" / "urdf" / "ur5_robot.urdf").is_file()
    assert find_robots_dir(found) == found.resolve()
    with pytest.raises(FileNotFoundError, match="robots_dir"):
        find_robots_dir(tmp_path)
    # the environment reaches the arm only through the settings the entry point builds
    monkeypatch.setenv("SOFTSIG_ROBOTS_DIR", str(tmp_path))
    assert find_robots_dir() == found  # library code does not read the environment
    assert Settings().robots_dir == tmp_path
    assert default_settings().robots_dir is None


def test_fk_at_zero_matches_hands_md(ur5: UR5) -> None:
    T = ur5.fk(np.zeros(6))
    # docs/design.md §8: tool0 at (0.81725, 0.19145, -0.00549) in base_link; the model gives z = d1 - d5 = -0.005491
    assert np.allclose(T[:3, 3], [0.81725, 0.19145, -0.00549], atol=2e-6)
    assert math.isclose(T[2, 3], D1 - D5, abs_tol=1e-9)
    assert np.allclose(T[:3, 2], [0.0, 1.0, 0.0], atol=1e-9)  # the flange faces +y at q = 0


def test_fk_matches_the_dh_table(ur5: UR5) -> None:
    """base_link is the DH base turned by pi about z; tool0 is the DH flange up to a constant rotation."""
    rng = np.random.default_rng(7)
    offsets = []
    for _ in range(20):
        q = ur5.random_configuration(rng)
        T_urdf = ur5.fk(q)
        T_dh = make_transform(rot_z(math.pi)) @ dh_flange(q)
        assert np.allclose(T_urdf[:3, 3], T_dh[:3, 3], atol=1e-9)
        offsets.append(T_dh[:3, :3].T @ T_urdf[:3, :3])
    assert all(np.allclose(o, offsets[0], atol=1e-9) for o in offsets)
    assert np.allclose(offsets[0], np.eye(3), atol=1e-9)


def test_frame_pose_and_jacobian(ur5: UR5) -> None:
    q = np.array([0.3, -1.2, 1.4, -1.6, -1.5, 0.2])
    assert np.allclose(ur5.frame_pose(q, "tool0"), ur5.fk(q))
    J = ur5.jacobian(q, local=False)
    dq = np.array([1e-7, -2e-7, 1e-7, 3e-7, -1e-7, 2e-7])
    dp = ur5.fk(q + dq)[:3, 3] - ur5.fk(q)[:3, 3]
    assert np.allclose(J[:3] @ dq, dp, atol=1e-12)


def top_grasp_target(x: float, y: float, z: float, yaw: float = 0.0) -> np.ndarray:
    """tool0 at (x, y, z) [m] with its z pointing down (a top grasp)."""
    return make_transform(rot_z(yaw) @ rot_x(math.pi), [x, y, z])


@pytest.mark.parametrize("analytic", [True, False])
def test_ik_round_trip_random_reachable_targets(ur5: UR5, analytic: bool) -> None:
    rng = np.random.default_rng(11)
    for _ in range(40):
        q_true = ur5.random_configuration(rng)
        target = ur5.fk(q_true)
        start = ur5.random_configuration(rng)  # a different, unrelated configuration
        res = ur5.solve_ik(target, start, seeds=12, analytic=analytic)
        assert res.success, res
        assert res.reason is None
        assert ur5.within_limits(res.q)
        dp, dr = UR5.pose_error(ur5.fk(res.q), target)
        assert dp <= 1e-5 and dr <= 1e-4
        assert res.position_residual == pytest.approx(dp, abs=1e-12)
        assert res.rotation_residual == pytest.approx(dr, abs=1e-9)


def test_ik_with_a_good_seed_returns_the_nearby_solution(ur5: UR5) -> None:
    rng = np.random.default_rng(5)
    for _ in range(20):
        q_true = ur5.random_configuration(rng)
        res = ur5.solve_ik(ur5.fk(q_true), q_true + rng.normal(0.0, 0.02, 6))
        assert res.success and res.iterations <= 10
        # the same branch (others are >= ~0.5 rad away); near a wrist/elbow singularity the solution is only
        # locally defined up to a small drift along the singular direction
        assert np.linalg.norm(res.q - q_true) < 0.05


def test_ik_unreachable_target_is_a_result_not_an_exception(ur5: UR5) -> None:
    far = top_grasp_target(3.0, 0.0, 0.3)
    res = ur5.solve_ik(far, np.zeros(6))
    assert not res.success and res.reason == "unreachable"
    assert res.position_residual > 2.0
    # inside the bounding ball of the reach test, but still out of reach: every seed fails
    near_miss = top_grasp_target(1.05, 0.0, 0.09)
    res = ur5.solve_ik(near_miss, np.zeros(6), seeds=4)
    assert not res.success and res.reason == "unreachable"
    assert res.seeds_tried == 1  # the closed form has no branch: no random restarts
    assert res.position_residual > 1e-3
    res = ur5.solve_ik(near_miss, np.zeros(6), seeds=4, analytic=False)
    assert not res.success and res.reason == "unreachable"
    assert res.seeds_tried == 5 and res.iterations > 0  # current_q + 4 random seeds, all failed
    assert res.position_residual > 1e-3
    assert ur5.within_limits(res.q)


@pytest.mark.parametrize("analytic", [True, False])
def test_the_solution_closest_to_current_q_wins(ur5: UR5, analytic: bool) -> None:
    target = top_grasp_target(0.45, 0.15, 0.25, yaw=0.4)
    every = ur5.solve_ik(target, None, seeds=40, exhaustive=True, analytic=analytic)
    assert every.success and len(every.solutions) >= 4  # UR5: up to 8 branches
    q_a, q_b = every.solutions[0], every.solutions[-1]
    for qs in (q_a, q_b):
        res = ur5.solve_ik(target, qs + 0.01, seeds=40, exhaustive=True, analytic=analytic)
        assert res.success
        assert np.allclose(res.q, qs, atol=1e-4)
    # from starts between two branches, the answer is at least as close as every known branch
    for w in (0.7, 0.5, 0.3):
        start = w * q_b + (1.0 - w) * q_a
        for exhaustive in (True, False) if analytic else (True,):
            res = ur5.solve_ik(target, start, seeds=40, exhaustive=exhaustive, analytic=analytic)
            best = np.linalg.norm(res.q - start)
            for s in every.solutions:
                wrapped = ur5.wrap_to_limits(s, start)
                assert wrapped is not None
                assert best <= np.linalg.norm(wrapped - start) + 1e-6


def test_closed_form_branches(ur5: UR5) -> None:
    """The closed-form UR IK (DH lengths read off the model) returns the true q among exact branches."""
    P = ur5.ur_parameters
    assert P is not None
    assert (P.d1, P.a2, P.a3, P.d4, P.d5, P.d6) == pytest.approx((D1, A2, A3, D4, D5, D6), abs=1e-12)
    rng = np.random.default_rng(3)
    for _ in range(100):
        q_true = ur5.random_configuration(rng)
        target = ur5.fk(q_true)
        branches = P.ik(target)
        assert 2 <= len(branches) <= 8
        for b in branches:
            dp, dr = UR5.pose_error(ur5.fk(b), target)
            assert dp < 1e-9 and dr < 1e-9
        gaps = [np.max(np.abs(np.remainder(b - q_true + math.pi, 2 * math.pi) - math.pi)) for b in branches]
        assert min(gaps) < 1e-6
    assert P.ik(top_grasp_target(1.2, 0.0, 0.1)) == []


def test_ik_is_deterministic(ur5: UR5) -> None:
    target = top_grasp_target(0.5, -0.1, 0.2)
    a = ur5.solve_ik(target, None, rng_seed=3, exhaustive=True)
    b = ur5.solve_ik(target, None, rng_seed=3, exhaustive=True)
    assert a.success and np.array_equal(a.q, b.q) and a.iterations == b.iterations


def test_wrap_to_limits(ur5: UR5) -> None:
    q = np.array([7.0, -7.0, 4.0, 0.5, 13.0, -0.5])
    w = ur5.wrap_to_limits(q)
    assert w is not None and ur5.within_limits(w)
    assert np.allclose(np.mod(w - q + math.pi, 2 * math.pi), math.pi)  # same angles
    assert math.isclose(w[2], 4.0 - 2 * math.pi)  # the elbow is limited to +-pi
    # the representative closest to the reference is chosen
    w2 = ur5.wrap_to_limits(np.zeros(6), reference=np.full(6, 5.0))
    assert w2 is not None
    assert np.allclose(w2, [2 * math.pi, 2 * math.pi, 0.0, 2 * math.pi, 2 * math.pi, 2 * math.pi])


def test_bad_input_raises(ur5: UR5) -> None:
    with pytest.raises(InvalidInput) as info:
        ur5.solve_ik(np.full((4, 4), np.nan))
    assert info.value.field == "target"
    with pytest.raises(InvalidInput):
        ur5.solve_ik(np.diag([2.0, 1.0, 1.0, 1.0]))  # not a rigid transform
    with pytest.raises(InvalidInput) as info:
        ur5.solve_ik(np.eye(4), current_q=[0.0, 1.0])
    assert info.value.field == "current_q"
    with pytest.raises(InvalidInput):
        ur5.fk([0.0, 0.0, math.inf, 0.0, 0.0, 0.0])


def test_without_current_q_the_home_configuration_is_the_reference(ur5: UR5) -> None:
    target = top_grasp_target(0.5, 0.1, 0.4)
    res = ur5.solve_ik(target)
    every = ur5.solve_ik(target, np.array(HOME_Q), exhaustive=True, seeds=0)
    assert res.success and every.success and len(every.solutions) == 8
    home = np.array(HOME_Q)
    dists = [float(np.linalg.norm(s - home)) for s in every.solutions]
    assert dists == sorted(dists)  # nearest first
    assert np.allclose(res.q, every.solutions[0], atol=1e-6)
    assert res.q[1] < -1.0 and res.q[2] > 1.0  # elbow up, like the home pose
    for s in every.solutions:
        dp, dr = UR5.pose_error(ur5.fk(s), target)
        assert dp <= 1e-5 and dr <= 1e-4


def test_closed_form_at_the_wrist_singularity(ur5: UR5) -> None:
    """With sin q5 = 0 the wrist's q6 is free: the branches take the caller's q6 and are still exact."""
    P = ur5.ur_parameters
    assert P is not None
    q_true = np.array([0.3, -1.1, 1.4, -1.9, 0.0, 0.7])
    target = ur5.fk(q_true)
    branches = P.ik_array(target, q6_default=0.25)
    assert len(branches) >= 2
    singular = [b for b in branches if abs(math.sin(b[4])) < 1e-9]
    assert singular and all(b[5] == pytest.approx(0.25) for b in singular)
    for b in branches:
        dp, dr = UR5.pose_error(ur5.fk(b), target)
        assert dp < 1e-9 and dr < 1e-9


def test_the_exact_nearest_branch_returns_what_the_seed_loop_returns(monkeypatch: pytest.MonkeyPatch) -> None:
    """The shortcut (the nearest closed-form branch accepted after one forward kinematics) answers exactly as the
    seed loop does without it: same q, residuals, counts and solutions, with and without a reference."""
    import softsig_service.arm.ur5 as ur5_module

    ur5 = load_ur5()
    rng = np.random.default_rng(21)
    cases = []
    for k in range(200):
        T = ur5.fk(ur5.random_configuration(rng))
        ref = None if k % 3 == 0 else ur5.random_configuration(rng)
        cases.append((T, ref))
    fast = [ur5.solve_ik_unchecked(T, ref, seeds=0 if k % 2 else 8) for k, (T, ref) in enumerate(cases)]
    monkeypatch.setattr(ur5_module, "settled", lambda *args: None)
    slow = [ur5.solve_ik_unchecked(T, ref, seeds=0 if k % 2 else 8) for k, (T, ref) in enumerate(cases)]
    for a, b in zip(fast, slow, strict=True):
        assert (a.success, a.iterations, a.seeds_tried, a.reason) == (b.success, b.iterations, b.seeds_tried, b.reason)
        assert np.array_equal(a.q, b.q)
        assert (a.position_residual, a.rotation_residual) == (b.position_residual, b.rotation_residual)
        assert len(a.solutions) == len(b.solutions)
        assert all(np.array_equal(x, y) for x, y in zip(a.solutions, b.solutions, strict=True))
    assert sum(r.success for r in fast) == len(cases)  # every target came from a configuration
