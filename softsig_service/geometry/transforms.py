"""Rotations, quaternions and rigid transforms: the only place where quaternion orders meet.

Conventions (docs/design.md §3):

* Internally a quaternion is a ``(4,)`` array in **wxyz** order (MuJoCo's order), unit norm, with the
  canonical sign ``w >= 0`` (``q`` and ``-q`` are the same rotation; we return the one with ``w >= 0``).
* Pinocchio's ``Quaternion.coeffs()`` and SciPy's ``Rotation.as_quat()`` use **xyzw**: convert with
  :func:`wxyz_to_xyzw` / :func:`xyzw_to_wxyz`, nowhere else.
* On the wire a quaternion is a mapping with named fields ``{"x", "y", "z", "w"}`` (geometry_msgs), and a
  pose is ``{"frame_id", "position": {"x", "y", "z"}, "orientation": {"x", "y", "z", "w"}}``.
* A rigid transform (an element of SE(3)) is a ``(4, 4)`` homogeneous matrix ``T_a_b`` that maps the
  coordinates of a point in frame ``b`` to frame ``a``: ``p_a = R p_b + t``. Compose with :func:`compose`
  (``T_a_c = T_a_b @ T_b_c``).
* Rotation matrices are proper (orthonormal, determinant +1); angles are in [rad], lengths in [m].
* World frame = the UR5 ``base_link`` (z up), named :data:`WORLD_FRAME`.

Malformed input (NaN, infinite values, a zero quaternion, a wrong shape) raises
:class:`softsig_service.errors.InvalidInput` naming the offending ``field``. Pure numpy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from softsig_service.errors import InvalidInput
from softsig_service.geometry.checks import _short, as_finite_array, check_rotation, wire_number
from softsig_service.geometry.quaternions import (
    ZERO_NORM,
    FloatArray,
    matrix_to_quat,
    quat_angle_between,
    quat_from_wire,
    quat_normalize,
    quat_to_matrix,
    unit_quat_to_wire,
    wxyz_to_xyzw,
    xyzw_to_wxyz,
)

WORLD_FRAME = "base_link"
"""Name of the world frame: the UR5 ``base_link`` (z up, the table top is the plane z = table_height)."""


# ----------------------------------------------------------------------------------------------------------
# rotations
# ----------------------------------------------------------------------------------------------------------


def rot_x(angle: float) -> FloatArray:
    """Rotation matrix about the x axis by ``angle`` [rad] (right-handed)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> FloatArray:
    """Rotation matrix about the y axis by ``angle`` [rad] (right-handed)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> FloatArray:
    """Rotation matrix about the z axis by ``angle`` [rad] (right-handed)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def axis_angle_to_matrix(axis: ArrayLike, angle: float, field: str = "axis") -> FloatArray:
    """Rotation matrix about the unit direction of ``axis`` by ``angle`` [rad] (Rodrigues)."""
    a = as_finite_array(axis, (3,), field)
    n = float(np.linalg.norm(a))
    if n < ZERO_NORM:
        raise InvalidInput("zero rotation axis", field=field, value=a.tolist())
    k = a / n
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def rotation_angle(R: ArrayLike) -> float:
    """Angle [rad] in [0, pi] of a rotation matrix (the norm of its rotation vector)."""
    M = as_finite_array(R, (3, 3), "rotation")
    c = 0.5 * (float(np.trace(M)) - 1.0)
    s = 0.5 * float(np.linalg.norm([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]]))
    return math.atan2(s, max(-1.0, min(1.0, c)))


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> FloatArray:
    """URDF roll-pitch-yaw [rad]: ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (fixed axes x, then y, then z)."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def yaw_of(R: ArrayLike) -> float:
    """Yaw [rad] in (-pi, pi]: the heading of the frame's x axis projected on the world xy plane.

    ``atan2(R[1, 0], R[0, 0])`` — the z angle of the ZYX (yaw-pitch-roll) decomposition. For a frame whose x
    axis is vertical the heading is undefined; the heading of its y axis minus pi/2 is returned instead.
    """
    M = as_finite_array(R, (3, 3), "rotation")
    if math.hypot(M[0, 0], M[1, 0]) < 1e-9:
        return _wrap_angle(math.atan2(M[1, 1], M[0, 1]) - 0.5 * math.pi)
    return math.atan2(M[1, 0], M[0, 0])


def _wrap_angle(a: float) -> float:
    """Wrap an angle [rad] into (-pi, pi]."""
    w = math.remainder(a, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


def wrap_angle(angle: float) -> float:
    """Wrap an angle [rad] into (-pi, pi]."""
    return _wrap_angle(float(angle))


# ----------------------------------------------------------------------------------------------------------
# SE(3) as 4x4 homogeneous matrices
# ----------------------------------------------------------------------------------------------------------


def make_transform(R: ArrayLike | None = None, p: ArrayLike | None = None) -> FloatArray:
    """Homogeneous 4x4 transform from a rotation ``R`` (default identity) and a translation ``p`` [m]."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = check_rotation(R)
    if p is not None:
        T[:3, 3] = as_finite_array(p, (3,), "position")
    return T


def transform_from_quat(p: ArrayLike, q_wxyz: ArrayLike) -> FloatArray:
    """Homogeneous 4x4 transform from a position [m] and a wxyz quaternion."""
    T = np.eye(4)
    T[:3, :3] = quat_to_matrix(q_wxyz, field="orientation")
    T[:3, 3] = as_finite_array(p, (3,), "position")
    return T


def check_transform(T: ArrayLike, field: str = "transform") -> FloatArray:
    """Return ``T`` as a 4x4 array if it is a rigid transform (rotation block proper, last row 0 0 0 1)."""
    M = as_finite_array(T, (4, 4), field)
    if not np.allclose(M[3], [0.0, 0.0, 0.0, 1.0], atol=1e-12):
        raise InvalidInput("last row of a homogeneous transform must be [0, 0, 0, 1]", field=field, value=M.tolist())
    check_rotation(M[:3, :3], field=field)
    return M


def compose(*transforms: ArrayLike) -> FloatArray:
    """Product ``T1 @ T2 @ ...`` of 4x4 transforms (``T_a_b, T_b_c -> T_a_c``); identity for no argument."""
    out = np.eye(4)
    for i, T in enumerate(transforms):
        out = out @ as_finite_array(T, (4, 4), f"transforms[{i}]")
    return out


def invert(T: ArrayLike) -> FloatArray:
    """Inverse of a rigid 4x4 transform (``T_a_b -> T_b_a``), using the transpose of the rotation."""
    M = as_finite_array(T, (4, 4), "transform")
    R = M[:3, :3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ M[:3, 3]
    return out


def apply(T: ArrayLike, points: ArrayLike) -> FloatArray:
    """Map points [m] of frame b to frame a with ``T_a_b``: one ``(3,)`` point or an ``(N, 3)`` array."""
    M = as_finite_array(T, (4, 4), "transform")
    P = np.asarray(points, dtype=np.float64)
    if P.shape == (3,):
        return M[:3, :3] @ P + M[:3, 3]
    if P.ndim != 2 or P.shape[1] != 3:
        raise InvalidInput(f"expected points of shape (3,) or (N, 3), got {P.shape}", field="points")
    return P @ M[:3, :3].T + M[:3, 3]


def translation(T: ArrayLike) -> FloatArray:
    """Translation part [m] of a 4x4 transform (a copy)."""
    return as_finite_array(T, (4, 4), "transform")[:3, 3].copy()


def rotation(T: ArrayLike) -> FloatArray:
    """Rotation part (3x3) of a 4x4 transform (a copy)."""
    return as_finite_array(T, (4, 4), "transform")[:3, :3].copy()


# ----------------------------------------------------------------------------------------------------------
# Pose
# ----------------------------------------------------------------------------------------------------------


def pose_wire(position: FloatArray, quaternion: FloatArray, frame_id: str) -> dict[str, Any]:
    """Wire form of a pose (:meth:`Pose.to_wire`) from a ``(3,)`` position [m] and a unit, canonical wxyz
    quaternion (e.g. :func:`~softsig_service.geometry.quaternions.rotation_to_quat`'s); nothing is checked."""
    p = position
    return {
        "frame_id": frame_id,
        "position": {"x": float(p[0]), "y": float(p[1]), "z": float(p[2])},
        "orientation": unit_quat_to_wire(quaternion),
    }


def _readonly(a: FloatArray) -> FloatArray:
    a = a.copy()
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Pose:
    """A rigid pose of a frame expressed in ``frame_id``: position [m] and a unit wxyz quaternion.

    The quaternion is normalised with the canonical sign ``w >= 0`` on construction; arrays are read-only.
    ``Pose(position, quaternion, frame_id)`` raises :class:`InvalidInput` for NaN, infinite values, wrong
    shapes, a zero quaternion or an empty ``frame_id``. Two poses compare equal when their frames match, their
    positions agree within 1e-12 m and their rotations within 1e-6 rad (``q`` and ``-q`` are one rotation).
    """

    position: FloatArray
    quaternion: FloatArray
    frame_id: str = WORLD_FRAME

    def __post_init__(self) -> None:
        p = as_finite_array(self.position, (3,), "pose.position")
        q = quat_normalize(self.quaternion, field="pose.orientation")
        if not isinstance(self.frame_id, str) or not self.frame_id:
            raise InvalidInput("frame_id must be a non-empty string", field="pose.frame_id", value=self.frame_id)
        object.__setattr__(self, "position", _readonly(p))
        object.__setattr__(self, "quaternion", _readonly(q))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Pose):
            return NotImplemented
        return (
            self.frame_id == other.frame_id
            and bool(np.allclose(self.position, other.position, rtol=0.0, atol=1e-12))
            and quat_angle_between(self.quaternion, other.quaternion) <= 1e-6
        )

    __hash__ = None  # type: ignore[assignment]

    @classmethod
    def from_matrix(cls, T: ArrayLike, frame_id: str = WORLD_FRAME) -> Pose:
        """Pose of a 4x4 homogeneous transform ``T_frame_id_child``."""
        M = check_transform(T)
        return cls(M[:3, 3], matrix_to_quat(M[:3, :3]), frame_id)

    @classmethod
    def from_xyzw(cls, position: ArrayLike, q_xyzw: ArrayLike, frame_id: str = WORLD_FRAME) -> Pose:
        """Pose from a position [m] and an xyzw quaternion (Pinocchio ``coeffs()``, SciPy ``as_quat()``)."""
        return cls(as_finite_array(position, (3,), "pose.position"), xyzw_to_wxyz(q_xyzw), frame_id)

    @classmethod
    def from_wire(cls, d: Mapping[str, Any], field: str = "pose") -> Pose:
        """Parse ``{"frame_id", "position": {"x","y","z"}, "orientation": {"x","y","z","w"}}``.

        ``field`` is the dotted path of the mapping in the request, used in error messages.
        """
        if not isinstance(d, Mapping):
            raise InvalidInput("expected a pose object", field=field, value=_short(d))
        allowed = {"frame_id", "position", "orientation"}
        unknown = set(d.keys()) - allowed
        if unknown:
            raise InvalidInput(f"unknown keys {sorted(unknown)}", field=field, choices=allowed)
        frame_id = d.get("frame_id")
        if not isinstance(frame_id, str) or not frame_id:
            raise InvalidInput("frame_id must be a non-empty string", field=f"{field}.frame_id", value=frame_id)
        pos_d = d.get("position")
        if not isinstance(pos_d, Mapping):
            raise InvalidInput("expected {x, y, z}", field=f"{field}.position", value=_short(pos_d))
        pos = np.array([wire_number(pos_d, k, f"{field}.position") for k in ("x", "y", "z")])
        ori_d = d.get("orientation")
        if not isinstance(ori_d, Mapping):
            raise InvalidInput("expected {x, y, z, w}", field=f"{field}.orientation", value=_short(ori_d))
        q = quat_from_wire(ori_d, field=f"{field}.orientation")
        return cls(pos, q, frame_id)

    def to_wire(self) -> dict[str, Any]:
        """Wire form ``{"frame_id", "position": {"x","y","z"}, "orientation": {"x","y","z","w"}}``."""
        return pose_wire(self.position, self.quaternion, self.frame_id)

    def matrix(self) -> FloatArray:
        """The 4x4 homogeneous transform ``T_frame_id_child`` of this pose."""
        return transform_from_quat(self.position, self.quaternion)

    @property
    def rotation_matrix(self) -> FloatArray:
        """The 3x3 rotation matrix of this pose."""
        return quat_to_matrix(self.quaternion)

    def quaternion_xyzw(self) -> FloatArray:
        """The orientation as xyzw (for Pinocchio ``Quaternion(coeffs)``/SciPy ``from_quat``)."""
        return wxyz_to_xyzw(self.quaternion)

    def compose(self, child: Pose) -> Pose:
        """``self ∘ child``: ``child`` is given in this pose's child frame; the result is in ``frame_id``."""
        return Pose.from_matrix(self.matrix() @ child.matrix(), self.frame_id)
