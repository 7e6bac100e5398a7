"""The warm-start IK shortcut: the nearest closed-form branch found by a best-first search and confirmed by one
forward kinematics answers as the full path does (the closed form, wrapping, sorting, the seed loop), and as an
independent FK check and the arm's whole solution set say it should."""

from __future__ import annotations

import math
from collections.abc import Callable
from types import SimpleNamespace
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from softsig_service.arm.ur5 import POSITION_TOLERANCE, ROTATION_TOLERANCE, UR5, _checked_target, load_ur5
from softsig_service.errors import InvalidInput
from softsig_service.geometry.checks import as_finite_array
from softsig_service.geometry.transforms import check_transform

# UR5: standard DH parameters [m] (Universal Robots' table), independent of the model's URDF
D1, A2, A3, D4, D5, D6 = 0.089159, 0.425, 0.39225, 0.10915, 0.09465, 0.0823
RZ_PI = np.diag([-1.0, -1.0, 1.0, 1.0])
"""``base_link`` is the DH base frame turned by pi about z."""

angle = st.floats(-math.pi, math.pi, allow_nan=False)
joints = st.lists(angle, min_size=6, max_size=6)
noise = st.lists(st.floats(-0.15, 0.15), min_size=6, max_size=6)
SINGULAR = ("none", "wrist", "elbow", "both")
"""Which singularity the true configuration is put at: the wrist's (sin q5 = 0, q6 free), the elbow's (q3 = 0, the
arm stretched), both."""


@pytest.fixture(scope="module")
def ur5() -> UR5:
    return load_ur5()


def dh_tool0(q: np.ndarray) -> np.ndarray:
    """``T_base_link_tool0`` from the published DH table (not from the model)."""
    a = [0.0, -A2, -A3, 0.0, 0.0, 0.0]
    d = [D1, 0.0, 0.0, D4, D5, D6]
    alpha = [math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0]
    T = RZ_PI.copy()
    for i in range(6):
        ct, st_, ca, sa = math.cos(q[i]), math.sin(q[i]), math.cos(alpha[i]), math.sin(alpha[i])
        T = T @ np.array([[ct, -st_ * ca, st_ * sa, a[i] * ct], [st_, ct * ca, -ct * sa, a[i] * st_],
                          [0.0, sa, ca, d[i]], [0.0, 0.0, 0.0, 1.0]])  # fmt: skip
    return T


def true_configuration(q: list[float], singular: str) -> np.ndarray:
    """``q`` [rad] with the joints of a ``singular`` case set."""
    qa = np.array(q)
    if singular in ("wrist", "both"):
        qa[4] = 0.0
    if singular in ("elbow", "both"):
        qa[2] = 0.0
    return qa


def nearest_by_sorting(ur5: UR5, T: np.ndarray, ref: np.ndarray, limits: SimpleNamespace) -> tuple[float, ...] | None:
    """What the seed loop tries first: every closed-form branch, wrapped into ``limits`` nearest ``ref``, sorted by
    distance (stable)."""
    P = ur5.ur_parameters
    assert P is not None
    branches = P.ik_array(T, q6_default=float(ref[5]))
    wrapped, valid = UR5._wrap_rows(limits, branches, ref)  # type: ignore[arg-type]
    wrapped = wrapped[valid]
    if len(wrapped) == 0:
        return None
    d = wrapped - ref
    return tuple(wrapped[int(np.argsort(np.sqrt((d * d).sum(axis=1)), kind="stable")[0])].tolist())


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    q=joints,
    singular=st.sampled_from(SINGULAR),
    warm=st.booleans(),
    dq=noise,
    far=st.lists(st.floats(-8.0, 8.0), min_size=6, max_size=6),
    narrow=st.booleans(),
    lo=st.lists(st.floats(-2 * math.pi, 0.0), min_size=6, max_size=6),
    hi=st.lists(st.floats(0.3, 2 * math.pi), min_size=6, max_size=6),
)
def test_nearest_branch_is_the_branch_the_seed_loop_tries_first(
    ur5: UR5,
    q: list[float],
    singular: str,
    warm: bool,
    dq: list[float],
    far: list[float],
    narrow: bool,
    lo: list[float],
    hi: list[float],
) -> None:
    """To the last bit, with the model's limits and with narrow ones (branches without a value in the limits,
    values clamped onto them), from warm starts and from anywhere in +-8 rad."""
    P = ur5.ur_parameters
    assert P is not None
    q_true = true_configuration(q, singular)
    T = ur5.fk(q_true)
    ref = q_true + np.array(dq) if warm else np.array(far)
    limits = SimpleNamespace(lower=np.array(lo), upper=np.array(hi)) if narrow else ur5
    got = P.nearest_branch(T.tolist(), ref.tolist(), limits.lower.tolist(), limits.upper.tolist())
    assert got == nearest_by_sorting(ur5, T, ref, limits)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(q=joints, singular=st.sampled_from(SINGULAR), warm=st.booleans(), dq=noise, other=joints)
def test_the_warm_start_answer_is_exact_and_the_nearest_valid_branch(
    ur5: UR5, q: list[float], singular: str, warm: bool, dq: list[float], other: list[float]
) -> None:
    """The answer is the seed loop's (the shortcut disabled) to the last bit; where the shortcut took it, it
    reaches the target by the model's FK and by the published DH table, and it is the valid closed-form branch
    nearest ``current_q``."""
    q_true = true_configuration(q, singular)
    T = ur5.fk(q_true)
    q0 = q_true + np.array(dq) if warm else np.array(other)
    res = ur5.solve_ik(T, q0)
    with mock.patch("softsig_service.arm.ur5.settled", lambda *args: None):
        slow = ur5.solve_ik(T, q0)
    assert (res.success, res.reason, res.iterations, res.seeds_tried) == (
        slow.success, slow.reason, slow.iterations, slow.seeds_tried
    )  # fmt: skip
    assert np.array_equal(res.q, slow.q)
    assert (res.position_residual, res.rotation_residual) == (slow.position_residual, slow.rotation_residual)
    assert len(res.solutions) == len(slow.solutions)
    assert all(np.array_equal(a, b) for a, b in zip(res.solutions, slow.solutions, strict=True))
    if res.iterations > 0 or not res.success:
        # not the shortcut's answer (no exact branch: a singular pose), the seed loop's as before; at the
        # stretched arm with the wrist singular (q3 = q5 = 0) the closed form can have no branch and the loop fail
        return
    assert res.seeds_tried == 1 and len(res.solutions) == 1 and ur5.within_limits(res.q)
    for T_fk in (dh_tool0(res.q), ur5.fk(res.q)):
        dp, dr = UR5.pose_error(T_fk, T)
        assert dp <= POSITION_TOLERANCE and dr <= ROTATION_TOLERANCE
    dp, dr = UR5.pose_error(ur5.fk(res.q), T)
    assert res.position_residual == pytest.approx(dp, abs=1e-12)
    assert res.rotation_residual == pytest.approx(dr, abs=1e-9)
    # every closed-form branch (q6 = q0[5] at the wrist singularity), wrapped into the limits nearest q0 by the
    # public wrap, kept where the model's FK reaches the target: the answer is one of them, and the nearest
    P = ur5.ur_parameters
    assert P is not None
    valid = []
    for b in P.ik_array(T, q6_default=float(q0[5])):
        w = ur5.wrap_to_limits(b, q0)
        if w is not None:
            dp, dr = UR5.pose_error(ur5.fk(w), T)
            if dp <= POSITION_TOLERANCE and dr <= ROTATION_TOLERANCE:
                valid.append(w)
    assert any(np.array_equal(res.q, w) for w in valid)
    assert float(np.linalg.norm(res.q - q0)) <= min(float(np.linalg.norm(w - q0)) for w in valid) + 1e-12


def test_the_shortcut_takes_the_common_case(ur5: UR5) -> None:
    """A warm start away from singularities: one forward kinematics, no numeric iteration."""
    rng = np.random.default_rng(4)
    for _ in range(200):
        q_true = ur5.random_configuration(rng)
        res = ur5.solve_ik(ur5.fk(q_true), q_true + rng.normal(0.0, 0.05, 6))
        assert res.success and res.iterations == 0 and res.seeds_tried == 1
        assert res.position_residual <= 1e-3 * POSITION_TOLERANCE
        assert res.rotation_residual <= 1e-3 * ROTATION_TOLERANCE


def _outcome(check: Callable[[object], object], value: object) -> object:
    """What ``check(value)`` returns, or ("InvalidInput", field) for the error it raises."""
    try:
        return check(value)
    except InvalidInput as exc:
        return ("InvalidInput", exc.field)


@settings(max_examples=300, deadline=None)
@given(
    rpy=st.lists(angle, min_size=3, max_size=3),
    p=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    entry=st.integers(0, 15),
    exponent=st.floats(-14.0, -3.0),
    sign=st.sampled_from((-1.0, 1.0)),
    special=st.sampled_from((None, math.nan, math.inf, -math.inf)),
)
def test_the_target_check_decides_as_check_transform(
    rpy: list[float], p: list[float], entry: int, exponent: float, sign: float, special: float | None
) -> None:
    """Rotations off by 1e-14 to 1e-3 in one entry, last rows off, NaN and infinities: accepted (the same array)
    or refused (InvalidInput on field ``target``) exactly as check_transform decides."""
    cr, sr = math.cos(rpy[0]), math.sin(rpy[0])
    cp, sp = math.cos(rpy[1]), math.sin(rpy[1])
    cy, sy = math.cos(rpy[2]), math.sin(rpy[2])
    T = np.eye(4)
    T[:3, :3] = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]) @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    T[:3, :3] = T[:3, :3] @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    T[:3, 3] = p
    T.flat[entry] += sign * 10.0**exponent if special is None else special
    fast = _outcome(_checked_target, T)
    slow = _outcome(lambda v: check_transform(v, field="target"), T)
    if isinstance(slow, np.ndarray):
        assert fast is T and slow is T
    else:
        assert fast == slow


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(q=st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=6, max_size=6))
def test_the_joint_check_decides_as_as_finite_array(ur5: UR5, q: list[float]) -> None:
    qa = np.array(q)
    fast = _outcome(lambda v: ur5.check_q(v, "current_q"), qa)
    slow = _outcome(lambda v: as_finite_array(v, (6,), "current_q"), qa)
    if isinstance(slow, np.ndarray):
        assert fast is qa and slow is qa
    else:
        assert fast == slow
