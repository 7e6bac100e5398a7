"""The arm's motions of a grasp, one source for the plan and the validation: the straight approach (pre-grasp to
grasp) and the lift (straight up from the grasp) as UR5 joint paths, and their timing.

Frames: flange ``tool0`` poses (4x4) in ``base_link``; joints [rad], time [s]. A motion follows the joint path
through :data:`WAYPOINTS` IK solutions evenly spaced on the Cartesian line (each seeded by the previous one: the
closed-form branch nearest it), linearly between them, timed by the minimum-jerk profile
``s(t) = 10 tau^3 - 15 tau^4 + 6 tau^5`` (``tau = t / T``: zero velocity and acceleration at both ends). ``T`` is
the nominal duration, lengthened when the profile would exceed the joints' velocity limit (the URDF's) or
:data:`ACCELERATION_LIMIT`. Between waypoints the flange leaves the line by at most the IK's chord error, which
:func:`path_deviation` measures.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from softsig_service.arm.ur5 import UR5

FloatArray = NDArray[np.float64]

WAYPOINTS = 11
"""IK solutions along each Cartesian line, ends included (10 segments: 1 cm each on a 10 cm approach)."""
LIFT = 0.15
"""[m] the lift after the grasp (docs/design.md §7)."""
APPROACH_TIME = 1.0
"""[s] nominal duration of the approach."""
LIFT_TIME = 1.0
"""[s] nominal duration of the lift."""
ACCELERATION_LIMIT = 4.0
"""[rad/s^2] the joints' acceleration bound, approximate: the UR5's URDF states no acceleration limit, so this is a
bound set here, above the 1.6-2.8 rad/s^2 peaks of the built-in hands' 1 s approaches and lifts (URScript's
``movej`` default, 1.4 rad/s^2, is a default, not a limit)."""
MAX_JOINT_STEP = 0.5
"""[rad] a joint moving more than this between neighbouring waypoints is a jump between IK branches."""
PEAK_VELOCITY = 15.0 / 8.0
"""Largest ``ds/dtau`` of the minimum-jerk profile (at ``tau = 1/2``)."""
PEAK_ACCELERATION = 10.0 / math.sqrt(3.0)
"""Largest ``|d^2 s / d tau^2|`` of the minimum-jerk profile (at ``tau = 1/2 -+ sqrt(3)/6``)."""


def quintic(tau: float) -> float:
    """The minimum-jerk profile ``s(tau)``, ``tau`` clipped to [0, 1]."""
    s = min(max(tau, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def quintic_rate(tau: float) -> float:
    """``ds/dtau`` of :func:`quintic`."""
    s = min(max(tau, 0.0), 1.0)
    return 30.0 * s * s * (1.0 - s) * (1.0 - s)


def interp(path: FloatArray, s: float) -> FloatArray:
    """The point at parameter ``s`` in [0, 1] on the piecewise-linear joint path ``path`` (K, 6)."""
    x = s * (len(path) - 1)
    k = min(int(x), len(path) - 2)
    u = x - k
    return np.asarray((1.0 - u) * path[k] + u * path[k + 1], dtype=np.float64)


def line_ik(ur5: UR5, T_start: FloatArray, T_end: FloatArray, q_start: FloatArray, n: int) -> FloatArray | None:
    """Joint positions (n, 6) [rad] at ``n`` evenly spaced flange poses on the straight line from ``T_start`` to
    ``T_end`` (the orientation of ``T_end`` throughout), each IK seeded by the previous solution from ``q_start``
    (the solution at ``T_start``). None if a point is unreachable or a joint would jump more than
    :data:`MAX_JOINT_STEP` between neighbours."""
    out = [np.asarray(q_start, dtype=np.float64)]
    q = out[0]
    for k in range(1, n):
        s = k / (n - 1)
        T = np.array(T_end, dtype=np.float64)
        T[:3, 3] = (1.0 - s) * T_start[:3, 3] + s * T_end[:3, 3]
        ik = ur5.solve_ik_unchecked(T, q, seeds=0)
        if not ik.success or float(np.max(np.abs(ik.q - q))) > MAX_JOINT_STEP:
            return None
        q = ik.q
        out.append(q)
    return np.array(out)


def arm_paths(
    ur5: UR5, T_pre: FloatArray, T_grasp: FloatArray, q_pre: FloatArray, lift: float = LIFT, waypoints: int = WAYPOINTS
) -> tuple[FloatArray, FloatArray] | str:
    """The joint paths (waypoints, 6) [rad] of the approach (``T_pre`` to ``T_grasp`` from ``q_pre``) and of the
    lift (``lift`` [m] straight up from the approach's end), or why one is unreachable (``unreachable:approach``,
    ``unreachable:lift``)."""
    approach = line_ik(ur5, T_pre, T_grasp, q_pre, waypoints)
    if approach is None:
        return "unreachable:approach"
    T_top = np.array(T_grasp, dtype=np.float64)
    T_top[2, 3] += lift
    up = line_ik(ur5, T_grasp, T_top, approach[-1], waypoints)
    if up is None:
        return "unreachable:lift"
    return approach, up


def duration(path: FloatArray, nominal: float, velocity_limit: FloatArray) -> float:
    """[s] the duration of the timed ``path``: ``nominal``, or longer where the minimum-jerk profile through the
    path would exceed a joint's ``velocity_limit`` [rad/s] or :data:`ACCELERATION_LIMIT` (a bound: the path's
    steepest segment at the profile's peak rate)."""
    segments = np.abs(np.diff(path, axis=0)) * (len(path) - 1)  # dq/ds per segment [rad]
    if segments.size == 0:
        return nominal
    rate = segments.max(axis=0)
    t_velocity = float(np.max(PEAK_VELOCITY * rate / np.asarray(velocity_limit)))
    t_acceleration = math.sqrt(float(np.max(PEAK_ACCELERATION * rate / ACCELERATION_LIMIT)))
    return max(nominal, t_velocity, t_acceleration)


@functools.cache
def _waypoint_phases(n: int) -> tuple[float, ...]:
    """The profile's ``tau`` in [0, 1] at which the path parameter reaches each of ``n`` evenly spaced waypoints
    (``quintic(tau_k) = k / (n - 1)``; bisection to 1e-15, computed once per ``n``)."""
    out = []
    for k in range(n):
        target = k / (n - 1)
        lo, hi = 0.0, 1.0
        for _ in range(52):  # s(tau) is increasing
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if quintic(mid) < target else (lo, mid)
        out.append(0.5 * (lo + hi))
    out[0], out[-1] = 0.0, 1.0  # exact at the ends
    return tuple(out)


def timed(path: FloatArray, total: float) -> tuple[list[float], FloatArray]:
    """The times [s] at which the profile of duration ``total`` passes the path's waypoints and the joint
    velocities [rad/s] there (the mean of the neighbouring segments' rates; zero at both ends)."""
    n = len(path)
    phases = _waypoint_phases(n)
    times = [tau * total for tau in phases]
    slopes = np.diff(path, axis=0) * (n - 1)  # dq/ds per segment
    velocities = np.zeros_like(path)
    for k in range(1, n - 1):
        velocities[k] = 0.5 * (slopes[k - 1] + slopes[k]) * quintic_rate(phases[k]) / total
    return times, velocities


def path_deviation(
    fk: Callable[[FloatArray], FloatArray], path: FloatArray, T_start: FloatArray, T_end: FloatArray, samples: int = 200
) -> float:
    """[m] the largest distance of the flange, followed along the joint path (``samples`` points, linear between
    waypoints) through the forward kinematics ``fk`` (joints [rad] to the 4x4 flange pose), from the straight
    line ``T_start`` to ``T_end``: a check of :func:`line_ik` with any FK (a test passes an independent one)."""
    a, b = T_start[:3, 3], T_end[:3, 3]
    d = b - a
    length2 = float(d @ d)
    worst = 0.0
    for s in np.linspace(0.0, 1.0, samples):
        p = fk(interp(path, float(s)))[:3, 3]
        t = 0.0 if length2 == 0.0 else min(max(float((p - a) @ d) / length2, 0.0), 1.0)
        worst = max(worst, float(np.linalg.norm(p - (a + t * d))))
    return worst
