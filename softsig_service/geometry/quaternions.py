"""Unit quaternions, ``(w, x, y, z)`` order inside softsig and ``{x, y, z, w}`` on the wire (geometry_msgs order); the
canonical sign is ``w >= 0``. Pure numpy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput
from softsig_service.geometry.checks import as_finite_array, check_rotation, wire_number

ZERO_NORM = 1e-9
"""A quaternion or rotation axis whose norm is below this names no rotation (it is rejected as zero)."""


FloatArray = NDArray[np.float64]


def quat_normalize(q_wxyz: ArrayLike, field: str = "quaternion") -> FloatArray:
    """Normalise a wxyz quaternion to unit norm with the canonical sign ``w >= 0``.

    When ``w == 0`` exactly the sign is fixed on the first non-zero of (x, y, z), made positive, so that the
    canonical form is unique. Raises :class:`InvalidInput` (naming ``field``) for NaN/inf or a zero
    quaternion.
    """
    q = as_finite_array(q_wxyz, (4,), field)
    n = float(np.linalg.norm(q))
    if n < ZERO_NORM:
        raise InvalidInput("zero quaternion does not describe a rotation", field=field, value=q.tolist())
    return _canonical_sign(q / n)


def _canonical_sign(q: FloatArray) -> FloatArray:
    """The unit quaternion ``q`` or ``-q``, whichever has ``w > 0`` (for ``w == 0``: the first non-zero of x, y, z)."""
    if q[0] < 0.0:
        return -q
    if q[0] == 0.0:
        nz = np.flatnonzero(q[1:])
        if nz.size and q[1 + nz[0]] < 0.0:
            return -q
    return q


def wxyz_to_xyzw(q_wxyz: ArrayLike) -> FloatArray:
    """Reorder a quaternion from wxyz (internal, MuJoCo) to xyzw (Pinocchio ``coeffs()``, SciPy)."""
    q = as_finite_array(q_wxyz, (4,), "quaternion")
    return np.array([q[1], q[2], q[3], q[0]])


def xyzw_to_wxyz(q_xyzw: ArrayLike) -> FloatArray:
    """Reorder a quaternion from xyzw (Pinocchio ``coeffs()``, SciPy) to wxyz (internal, MuJoCo)."""
    q = as_finite_array(q_xyzw, (4,), "quaternion")
    return np.array([q[3], q[0], q[1], q[2]])


def quat_to_wire(q_wxyz: ArrayLike) -> dict[str, float]:
    """Wire form ``{"x", "y", "z", "w"}`` (geometry_msgs/Quaternion) of a wxyz quaternion, normalised."""
    return unit_quat_to_wire(quat_normalize(q_wxyz))


def unit_quat_to_wire(q: FloatArray) -> dict[str, float]:
    """:func:`quat_to_wire` of a quaternion that is unit and canonical already (no checks, no normalisation)."""
    return {"x": float(q[1]), "y": float(q[2]), "z": float(q[3]), "w": float(q[0])}


def quat_from_wire(d: Mapping[str, Any], field: str = "orientation") -> FloatArray:
    """Read a wire quaternion ``{"x", "y", "z", "w"}`` into a canonical wxyz array.

    Every one of the four keys must be present and a finite number; ``field`` names the mapping in errors
    (e.g. ``pose.orientation``).
    """
    w, x, y, z = (wire_number(d, k, field) for k in ("w", "x", "y", "z"))
    return quat_normalize([w, x, y, z], field=field)


def quat_multiply(a_wxyz: ArrayLike, b_wxyz: ArrayLike) -> FloatArray:
    """Hamilton product ``a * b`` of two wxyz quaternions (rotation ``b`` first, then ``a``), canonical."""
    a = as_finite_array(a_wxyz, (4,), "quaternion")
    b = as_finite_array(b_wxyz, (4,), "quaternion")
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return quat_normalize(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def quat_conjugate(q_wxyz: ArrayLike) -> FloatArray:
    """Inverse rotation of a unit wxyz quaternion (canonical sign)."""
    q = quat_normalize(q_wxyz)
    return quat_normalize([q[0], -q[1], -q[2], -q[3]])


def quat_to_matrix(q_wxyz: ArrayLike, field: str = "quaternion") -> FloatArray:
    """Rotation matrix (3x3) of a wxyz quaternion (normalised first)."""
    w, x, y, z = quat_normalize(q_wxyz, field=field)
    return np.array(
        [
            [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
            [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
            [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(R: ArrayLike, field: str = "rotation") -> FloatArray:
    """Canonical wxyz quaternion of a rotation matrix (Shepperd's method, numerically stable for every angle).

    Raises :class:`InvalidInput` when ``R`` is not a proper rotation (within 1e-6).
    """
    return rotation_to_quat(check_rotation(R, field=field))


def rotation_to_quat(M: FloatArray) -> FloatArray:
    """:func:`matrix_to_quat` of a ``(3, 3)`` float array the caller knows to be a proper rotation (the planner's
    own poses): nothing is checked."""
    tr = M[0, 0] + M[1, 1] + M[2, 2]
    diag = (M[0, 0], M[1, 1], M[2, 2])
    if tr >= max(diag):
        s = 2.0 * math.sqrt(max(1.0 + tr, 0.0))
        q = [0.25 * s, (M[2, 1] - M[1, 2]) / s, (M[0, 2] - M[2, 0]) / s, (M[1, 0] - M[0, 1]) / s]
    elif diag[0] >= diag[1] and diag[0] >= diag[2]:
        s = 2.0 * math.sqrt(max(1.0 + M[0, 0] - M[1, 1] - M[2, 2], 0.0))
        q = [(M[2, 1] - M[1, 2]) / s, 0.25 * s, (M[0, 1] + M[1, 0]) / s, (M[0, 2] + M[2, 0]) / s]
    elif diag[1] >= diag[2]:
        s = 2.0 * math.sqrt(max(1.0 + M[1, 1] - M[0, 0] - M[2, 2], 0.0))
        q = [(M[0, 2] - M[2, 0]) / s, (M[0, 1] + M[1, 0]) / s, 0.25 * s, (M[1, 2] + M[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(max(1.0 + M[2, 2] - M[0, 0] - M[1, 1], 0.0))
        q = [(M[1, 0] - M[0, 1]) / s, (M[0, 2] + M[2, 0]) / s, (M[1, 2] + M[2, 1]) / s, 0.25 * s]
    qa = np.array(q, dtype=np.float64)
    return _canonical_sign(qa / math.sqrt(float(qa @ qa)))


def quat_angle_between(a_wxyz: ArrayLike, b_wxyz: ArrayLike) -> float:
    """Angle [rad] in [0, pi] of the rotation taking ``a`` to ``b`` (sign-insensitive)."""
    a = quat_normalize(a_wxyz)
    b = quat_normalize(b_wxyz)
    d = min(1.0, abs(float(np.dot(a, b))))
    return 2.0 * math.acos(d)
