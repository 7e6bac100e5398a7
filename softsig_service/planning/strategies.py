"""Top-grasp strategies as pure math: S (alignment with the object's major axis) and the alignment measures of both.

World frame = UR5 ``base_link`` (z up); hand frame per docs/design.md §3 (+z approach, +x across the palm). A top grasp
has hand +z pointing down. Strategy C's optimisation lives in :mod:`softsig_service.planning.wrist_pose`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from softsig_service.planning.wrist_pose import hand_rotation

STRATEGIES = ("S", "C", "R")
"""S: bounding box; C: closure signature; R: robust to the stated pose uncertainty (needs a capture model)."""


def axis_angle_between_lines(u: NDArray[np.float64], v: NDArray[np.float64]) -> float:
    """Angle [rad] in [0, pi/2] between two lines (directions without sign) in the horizontal plane."""
    a = np.asarray(u, dtype=float)[:2]
    b = np.asarray(v, dtype=float)[:2]
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if na < 1e-12 or nb < 1e-12:
        return math.pi / 2
    c = abs(float(a @ b)) / (na * nb)
    return math.acos(min(1.0, c))


def strategy_s_poses(
    object_center: NDArray[np.float64], major_axis: NDArray[np.float64], hand_center: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """Strategy S: hand +z down, hand +x along the object's major axis, placement point over the object's centre.

    ``hand_center`` [m] is the placement point, a point of the hand frame placed vertically above
    ``object_center`` [m, world]. The planner (:mod:`softsig_service.planning.planner`) passes
    ``HandPlanningModel.placement_point("S", PlanRequest.placement)``: by default (``placement="open_centre"``)
    the centre c_0 of the open hand's reference-point ellipsoid; with ``"grasp_centre"`` the centre c_T of the
    closed hand's reference-point ellipsoid (strategy C puts the same point there, so S and C differ only in
    yaw); with ``"per_strategy"`` the centre of the open reference points' bounding box. The flange height is left
    at the object's centre height (the planner sets it by descending along the approach). Both yaws (the axis
    has no sign) are returned.
    """
    return relative_poses(object_center, major_axis, hand_center, 0.0, 0.0, 0.0)


def relative_poses(
    object_center: NDArray[np.float64],
    major_axis: NDArray[np.float64],
    hand_point: NDArray[np.float64],
    theta: float,
    u: float,
    v: float,
) -> list[NDArray[np.float64]]:
    """Flange poses (4x4, world) that put the hand at relative pose ``(theta, u, v)`` to the object: hand +z down,
    the object's major axis ``theta`` [rad] from the hand's +x (about world +z), the object's centre at ``u``,
    ``v`` [m] from the placement point ``hand_point`` (hand frame) along the hand's +x, +y. Both yaws a half
    turn apart are returned (the footprint is symmetric under a half turn, so both are the same relative pose).
    The flange height is left at the object's centre height (the planner descends). Strategy S is
    ``theta = u = v = 0``."""
    o1 = np.asarray(major_axis, dtype=float)
    c = np.asarray(object_center, dtype=float)
    yaw0 = math.atan2(o1[1], o1[0]) - theta
    poses = []
    for yaw in (yaw0, yaw0 + math.pi):
        R = hand_rotation(math.remainder(yaw, 2 * math.pi), 0.0, 0.0)
        T = np.eye(4)
        T[:3, :3] = R
        point = c - u * R[:, 0] - v * R[:, 1]  # where the placement point goes
        T[:3, 3] = point - R @ np.asarray(hand_point, dtype=float)
        T[2, 3] = c[2]
        poses.append(T)
    return poses
