"""Quaternion orders, rotations and SE(3) helpers of softsig_service.geometry.transforms."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from softsig_service.errors import InvalidInput
from softsig_service.geometry import quaternions as qt
from softsig_service.geometry import transforms as tf

finite = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False, allow_infinity=False)
coords = st.floats(min_value=-5.0, max_value=5.0, allow_nan=False, allow_infinity=False)
angles = st.floats(min_value=-10.0, max_value=10.0, allow_nan=False, allow_infinity=False)


@st.composite
def quaternions(draw: st.DrawFn) -> np.ndarray:
    """Random non-degenerate wxyz quaternions (not normalised, any sign)."""
    q = np.array([draw(finite) for _ in range(4)])
    if np.linalg.norm(q) < 0.1:
        q = q + np.array([0.5, 0.0, 0.0, 0.0])
    return q


@st.composite
def transforms(draw: st.DrawFn) -> np.ndarray:
    return tf.transform_from_quat([draw(coords) for _ in range(3)], draw(quaternions()))


def same_rotation(a: np.ndarray, b: np.ndarray, tol: float = 1e-9) -> bool:
    """wxyz quaternions a and b name the same rotation (q ~ -q)."""
    return bool(np.allclose(a, b, atol=tol) or np.allclose(a, -b, atol=tol))


# -- quaternion orders --------------------------------------------------------------------------------------


@given(quaternions())
def test_wxyz_xyzw_round_trip(q: np.ndarray) -> None:
    xyzw = qt.wxyz_to_xyzw(q)
    assert xyzw[3] == q[0] and np.array_equal(xyzw[:3], q[1:])
    assert np.array_equal(qt.xyzw_to_wxyz(xyzw), q)


@given(quaternions())
def test_normalize_is_unit_and_canonical(q: np.ndarray) -> None:
    n = qt.quat_normalize(q)
    assert math.isclose(float(np.linalg.norm(n)), 1.0, rel_tol=1e-12)
    assert n[0] >= 0.0
    assert same_rotation(n, q / np.linalg.norm(q))
    assert np.allclose(qt.quat_normalize(-q), n, atol=1e-12)  # q and -q give the same canonical form


@given(quaternions())
def test_quat_matrix_round_trip(q: np.ndarray) -> None:
    R = qt.quat_to_matrix(q)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert math.isclose(float(np.linalg.det(R)), 1.0, rel_tol=1e-12)
    back = qt.matrix_to_quat(R)
    assert back[0] >= 0.0
    assert same_rotation(back, qt.quat_normalize(q), tol=1e-9)
    assert np.allclose(qt.quat_to_matrix(back), R, atol=1e-12)


@given(quaternions())
def test_matrix_agrees_with_scipy_xyzw(q: np.ndarray) -> None:
    """SciPy takes xyzw: our wxyz -> xyzw conversion must feed it the same rotation."""
    R_ours = qt.quat_to_matrix(q)
    R_scipy = Rotation.from_quat(qt.wxyz_to_xyzw(qt.quat_normalize(q))).as_matrix()
    assert np.allclose(R_ours, R_scipy, atol=1e-12)
    back = qt.xyzw_to_wxyz(Rotation.from_matrix(R_ours).as_quat())
    assert same_rotation(back, qt.quat_normalize(q))


@given(quaternions())
def test_matrix_agrees_with_pinocchio_coeffs(q: np.ndarray) -> None:
    """Pinocchio's Quaternion.coeffs() is xyzw."""
    R = qt.quat_to_matrix(q)
    coeffs = np.array(pin.Quaternion(R).coeffs())
    assert same_rotation(qt.xyzw_to_wxyz(coeffs), qt.matrix_to_quat(R), tol=1e-9)


@given(quaternions())
def test_wire_round_trip(q: np.ndarray) -> None:
    wire = qt.quat_to_wire(q)
    assert set(wire) == {"x", "y", "z", "w"}
    n = qt.quat_normalize(q)
    assert (wire["w"], wire["x"], wire["y"], wire["z"]) == tuple(float(v) for v in n)
    assert np.allclose(qt.quat_from_wire(wire), n, atol=1e-15)


def test_wire_fields_are_named_not_ordered() -> None:
    # a 90 deg rotation about z: w = cos 45, z = sin 45, whatever the key order
    d = {"z": math.sqrt(0.5), "w": math.sqrt(0.5), "y": 0.0, "x": 0.0}
    R = qt.quat_to_matrix(qt.quat_from_wire(d))
    assert np.allclose(R, tf.rot_z(math.pi / 2), atol=1e-12)


@given(quaternions(), quaternions())
def test_multiply_matches_matrix_product(a: np.ndarray, b: np.ndarray) -> None:
    ab = qt.quat_multiply(a, b)
    assert np.allclose(qt.quat_to_matrix(ab), qt.quat_to_matrix(a) @ qt.quat_to_matrix(b), atol=1e-12)
    ident = qt.quat_multiply(a, qt.quat_conjugate(a))
    assert np.allclose(ident, [1.0, 0.0, 0.0, 0.0], atol=1e-12)


# -- rotations ---------------------------------------------------------------------------------------------


@given(angles)
def test_axis_rotations_match_axis_angle(a: float) -> None:
    assert np.allclose(tf.rot_x(a), tf.axis_angle_to_matrix([2.0, 0, 0], a), atol=1e-12)
    assert np.allclose(tf.rot_y(a), tf.axis_angle_to_matrix([0, 3.0, 0], a), atol=1e-12)
    assert np.allclose(tf.rot_z(a), tf.axis_angle_to_matrix([0, 0, 0.5], a), atol=1e-12)
    assert np.allclose(tf.rot_z(a) @ np.array([1.0, 0, 0]), [math.cos(a), math.sin(a), 0.0], atol=1e-12)


@given(st.floats(min_value=0.0, max_value=math.pi), st.tuples(finite, finite, finite))
def test_rotation_angle(theta: float, axis: tuple[float, float, float]) -> None:
    if np.linalg.norm(axis) < 0.1:
        axis = (0.0, 0.0, 1.0)
    assert math.isclose(tf.rotation_angle(tf.axis_angle_to_matrix(axis, theta)), theta, abs_tol=1e-7)


@given(angles, st.floats(min_value=-1.2, max_value=1.2), st.floats(min_value=-3.0, max_value=3.0))
def test_yaw_of(yaw: float, pitch: float, roll: float) -> None:
    R = tf.rpy_to_matrix(roll, pitch, yaw)
    assert math.isclose(tf.yaw_of(R), tf.wrap_angle(yaw), abs_tol=1e-9) or math.isclose(
        abs(tf.wrap_angle(yaw)), math.pi, abs_tol=1e-9
    )


def test_yaw_of_top_grasp_frame() -> None:
    # hand +z down (world -z), hand x along yaw 0.7: R = Rz(0.7) Rx(pi)
    R = tf.rot_z(0.7) @ tf.rot_x(math.pi)
    assert np.allclose(R[:, 2], [0.0, 0.0, -1.0], atol=1e-12)
    assert math.isclose(tf.yaw_of(R), 0.7, abs_tol=1e-12)


def test_wrap_angle() -> None:
    assert math.isclose(tf.wrap_angle(3 * math.pi / 2), -math.pi / 2)
    assert tf.wrap_angle(-math.pi) == math.pi
    assert math.isclose(tf.wrap_angle(7.0), 7.0 - 2 * math.pi)


# -- SE(3) -------------------------------------------------------------------------------------------------


@given(transforms(), transforms(), st.tuples(coords, coords, coords))
def test_compose_invert_apply(A: np.ndarray, B: np.ndarray, p: tuple[float, float, float]) -> None:
    AB = tf.compose(A, B)
    assert np.allclose(AB, A @ B)
    assert np.allclose(tf.compose(A, tf.invert(A)), np.eye(4), atol=1e-12)
    assert np.allclose(tf.invert(AB), tf.compose(tf.invert(B), tf.invert(A)), atol=1e-10)
    assert np.allclose(tf.apply(AB, p), tf.apply(A, tf.apply(B, p)), atol=1e-10)
    pts = np.array([p, [0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    assert np.allclose(tf.apply(A, pts)[1], tf.translation(A))
    assert np.allclose(tf.apply(tf.invert(A), tf.apply(A, pts)), pts, atol=1e-10)


def test_compose_of_nothing_is_identity() -> None:
    assert np.array_equal(tf.compose(), np.eye(4))


def test_apply_is_rotation_then_translation() -> None:
    T = tf.make_transform(tf.rot_z(math.pi / 2), [1.0, 0.0, 0.0])
    assert np.allclose(tf.apply(T, [1.0, 0.0, 0.0]), [1.0, 1.0, 0.0])


# -- Pose --------------------------------------------------------------------------------------------------


@given(transforms())
def test_pose_matrix_and_wire_round_trip(T: np.ndarray) -> None:
    pose = tf.Pose.from_matrix(T, frame_id="base_link")
    assert np.allclose(pose.matrix(), T, atol=1e-12)
    wire = pose.to_wire()
    assert wire["frame_id"] == "base_link"
    assert set(wire["position"]) == {"x", "y", "z"} and set(wire["orientation"]) == {"x", "y", "z", "w"}
    back = tf.Pose.from_wire(wire)
    assert back == pose
    assert np.allclose(back.matrix(), T, atol=1e-12)
    assert same_rotation(qt.xyzw_to_wxyz(pose.quaternion_xyzw()), pose.quaternion)


def test_pose_is_canonical_and_read_only() -> None:
    pose = tf.Pose(np.array([1.0, 2.0, 3.0]), np.array([-2.0, 0.0, 0.0, 0.0]))
    assert np.array_equal(pose.quaternion, [1.0, 0.0, 0.0, 0.0])
    assert pose.frame_id == tf.WORLD_FRAME == "base_link"
    with pytest.raises(ValueError):
        pose.position[0] = 5.0


def test_pose_compose() -> None:
    a = tf.Pose.from_matrix(tf.make_transform(tf.rot_z(math.pi / 2), [1.0, 0.0, 0.0]))
    b = tf.Pose.from_matrix(tf.make_transform(None, [1.0, 0.0, 0.0]), frame_id="child")
    c = a.compose(b)
    assert c.frame_id == a.frame_id
    assert np.allclose(c.position, [1.0, 1.0, 0.0])


# -- malformed input ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("q", "message"),
    [([0.0, 0.0, 0.0, 0.0], "zero quaternion"), ([math.nan, 0, 0, 1], "NaN"), ([math.inf, 0, 0, 1], "NaN")],
)
def test_bad_quaternions_are_rejected_with_field(q: list[float], message: str) -> None:
    with pytest.raises(InvalidInput, match=message) as info:
        qt.quat_normalize(q, field="grasp.orientation")
    assert info.value.field == "grasp.orientation"


def test_bad_wire_poses_name_the_field() -> None:
    good = {
        "frame_id": "base_link",
        "position": {"x": 0, "y": 0, "z": 0},
        "orientation": {"x": 0, "y": 0, "z": 0, "w": 1},
    }
    tf.Pose.from_wire(good)
    cases: list[tuple[dict, str]] = [
        ({**good, "orientation": {"x": 0, "y": 0, "z": 0}}, "plan.grasp.orientation.w"),
        ({**good, "orientation": {"x": 0, "y": 0, "z": 0, "w": 0}}, "plan.grasp.orientation"),
        ({**good, "orientation": {"x": 0, "y": 0, "z": 0, "w": math.nan}}, "plan.grasp.orientation.w"),
        ({**good, "orientation": {"x": 0, "y": 0, "z": 0, "w": True}}, "plan.grasp.orientation.w"),
        ({**good, "position": {"x": 0, "y": "1", "z": 0}}, "plan.grasp.position.y"),
        ({**good, "position": {"x": 0, "y": 0, "z": math.inf}}, "plan.grasp.position.z"),
        ({**good, "frame_id": ""}, "plan.grasp.frame_id"),
        ({**good, "extra": 1}, "plan.grasp"),
    ]
    for d, field in cases:
        with pytest.raises(InvalidInput) as info:
            tf.Pose.from_wire(d, field="plan.grasp")
        assert info.value.field == field, (d, info.value)


def test_bad_matrices_are_rejected() -> None:
    with pytest.raises(InvalidInput):
        qt.matrix_to_quat(np.diag([1.0, 1.0, -1.0]))  # a reflection
    with pytest.raises(InvalidInput):
        qt.matrix_to_quat(2.0 * np.eye(3))
    with pytest.raises(InvalidInput):
        tf.check_transform(np.ones((4, 4)))
    with pytest.raises(InvalidInput) as info:
        tf.Pose(np.array([0.0, math.nan, 0.0]), np.array([1.0, 0, 0, 0]))
    assert info.value.field == "pose.position"


@settings(max_examples=50)
@given(st.floats(min_value=0.0, max_value=2 * math.pi))
def test_matrix_to_quat_near_pi(theta: float) -> None:
    """Shepperd's branches: rotations near pi about every axis come back exactly."""
    for axis in ([1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [1.0, 1.0, 0]):
        R = tf.axis_angle_to_matrix(axis, theta)
        assert np.allclose(qt.quat_to_matrix(qt.matrix_to_quat(R)), R, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
def test_the_unchecked_pose_wire_equals_the_checked_one(seed: int, x: float, y: float, z: float) -> None:
    """The planner's unchecked path (rotation_to_quat, pose_wire) writes what Pose.from_matrix(...).to_wire() writes,
    to rounding, and its quaternion is unit with w >= 0 and gives back the rotation."""
    R = Rotation.random(random_state=seed).as_matrix()
    T = tf.make_transform(R, [x, y, z])
    q = qt.rotation_to_quat(R)
    assert abs(float(np.linalg.norm(q)) - 1.0) <= 1e-15 and q[0] >= 0.0
    np.testing.assert_allclose(qt.quat_to_matrix(q), R, atol=1e-12)
    fast = tf.pose_wire(T[:3, 3], q, "base_link")
    slow = tf.Pose.from_matrix(T, "base_link").to_wire()
    assert fast["frame_id"] == slow["frame_id"] and fast["position"] == slow["position"]
    for k in "xyzw":
        assert fast["orientation"][k] == pytest.approx(slow["orientation"][k], abs=1e-15)
