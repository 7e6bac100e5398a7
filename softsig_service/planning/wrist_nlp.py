"""Strategy C's wrist pose over the arm's joints: a CasADi NLP (Ipopt) whose variables are the six UR5 joint angles,
so that reachability and the joint limits are part of the problem, and whose wrist may tilt within an approach cone.

Frames: world = UR5 ``base_link`` (z up). The grasp frame's pose is ``T_G(q) = FK(q) T_HG`` (the symbolic FK of
:mod:`softsig_service.planning.arm_fk` and the hand's grasp frame in the flange frame); its +z is the approach.

Cost (each term zero at an ideal grasp):

* alignment: the squared sine of the angle between the closure signature ``R u`` projected on the plane across
  the object's up axis ``n`` and the object's closing axis ``a`` (unit, in that plane; an axis: both signs): for an
  object resting upright, the horizontal projection, as the closed form of
  :mod:`softsig_service.planning.wrist_pose`;
* approach: ``1 - z . (-n)`` weighted by :data:`APPROACH_WEIGHT`, the approach ``z`` along the object's down
  ``-n`` (``n`` its up axis: world +z for an object resting upright, tilted with a tilted object);
* centring: the placement point's offset from the object's centre across the approach, per
  :data:`~softsig_service.planning.wrist_pose.CENTRING_SCALE`, weighted 1e-3, and its distance before the centre
  along the approach from the stated ``stand_off`` (per :data:`~softsig_service.planning.wrist_pose.DEPTH_SCALE`),
  weighted 1e-3: the grasp's depth, which the descent found for the untilted pose.

Constraints: the approach within ``cone`` [rad] of straight down (``z . (-e_z) >= cos(cone)``); every open-hand
reference point ``margin`` [m] above the table; joints (two more sets of six variables) that put the flange, turned
the same way, at the pre-grasp (back along the approach) and at the top of the lift, so that the whole motion is
within reach; every joint :data:`LIMIT_MARGIN` [rad] inside its limits. The
planner's descent then sets the depth along the approach, as for the closed form.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from softsig_service.arm.ur5 import UR5
from softsig_service.planning.arm_fk import symbolic_fk
from softsig_service.planning.wrist_pose import CENTRING_SCALE, DEPTH_SCALE, MIN_HORIZONTAL_CS

APPROACH_WEIGHT = 0.1
"""Weight of the approach term: alignment first, then the approach along the object's down axis."""
LIMIT_MARGIN = 0.05
"""[rad] the joints stay this far inside their limits."""
DEFAULT_CONE = math.radians(30.0)
"""[rad] the default approach cone: up to 30 degrees from straight down (a stated choice: wide enough for a tilted
object or the workspace's edge, narrow enough to stay a top grasp)."""
ALIGNED = 1e-6
"""Largest alignment cost (about 1e-3 rad) of a solution that counts as aligned."""
REACHED = 1e-6
"""[m, rad] largest miss of the pre-grasp and lift-top flange poses by their joints."""
CENTRED = 0.002
"""[m] largest offset across the approach of a solution's placement point from the object's centre."""
_OPTIONS: dict[str, Any] = {
    "ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": 1e-10, "ipopt.max_iter": 300,
}  # fmt: skip


@dataclass(frozen=True)
class JointWristSolution:
    """The NLP's answer: joints ``q`` [rad], the grasp frame's pose ``T_world_grasp`` (4x4), its tilt from straight
    down [rad], the alignment error [rad], the placement point's offset across the approach [m], success and the
    solver's status and iterations."""

    success: bool
    status: str
    q: NDArray[np.float64]
    T_world_grasp: NDArray[np.float64]
    tilt: float
    alignment_error: float
    centring_error: float
    iterations: int


_LOCAL = threading.local()


def _solver(ur5: UR5, n_points: int) -> tuple[ca.Function, ca.Function]:
    """This thread's compiled solver and its expression function for ``n_points`` reference points."""
    cache: dict[tuple[int, int], tuple[ca.Function, ca.Function]] = getattr(_LOCAL, "solvers", None) or {}
    _LOCAL.solvers = cache
    key = (id(ur5.model), n_points)
    if key not in cache:
        x = ca.SX.sym("x", 18)  # the joints at the grasp, at the pre-grasp and at the top of the lift
        q, q_pre, q_top = x[:6], x[6:12], x[12:]
        # parameters: T_HG (16), u, placement point, centre, closing axis, up (3 each), table, margin, cos(cone),
        # stand-off, approach distance, lift, points (3 n)
        p = ca.SX.sym("p", 16 + 15 + 6 + 3 * n_points)
        T_HG = ca.reshape(p[:16], 4, 4)
        u, pa, c, a, n = (p[16 + 3 * i : 19 + 3 * i] for i in range(5))
        table, margin, cos_cone, stand_off, distance, lift = (p[31 + i] for i in range(6))
        P = ca.reshape(p[37:], 3, n_points)
        fk = symbolic_fk(ur5)
        F = fk(q)
        T = F @ T_HG
        R, t = T[:3, :3], T[:3, 3]
        z = R[:, 2]
        w = R @ u
        w_across = w - ca.dot(w, n) * n  # the CS projected on the plane across the object's up axis
        align = 1 - ca.dot(w_across, a) ** 2 / (ca.sumsqr(w_across) + 1e-12)
        approach = 1 - ca.dot(z, -n)
        d = t + R @ pa - c
        depth = ca.dot(d, z)
        lateral = d - depth * z
        cost = align + APPROACH_WEIGHT * approach + 1e-3 * (ca.sumsqr(lateral) / CENTRING_SCALE**2
                                                           + (depth + stand_off) ** 2 / DEPTH_SCALE**2)  # fmt: skip
        heights = (R @ P + ca.repmat(t, 1, n_points))[2, :].T - table - margin

        def same_flange(q_other: Any, shift: Any) -> Any:
            """The flange at ``q_other`` where the grasp's flange is, moved by ``shift``, turned the same way."""
            G = fk(q_other)
            E = G[:3, :3].T @ F[:3, :3]
            return ca.vertcat(G[:3, 3] - F[:3, 3] - shift, 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0],
                                                                              E[1, 0] - E[0, 1]))  # fmt: skip

        reach = ca.vertcat(same_flange(q_pre, -distance * z), same_flange(q_top, ca.vertcat(0, 0, lift)))
        g = ca.vertcat(-z[2] - cos_cone, heights, reach)
        nlp = {"x": x, "p": p, "f": cost, "g": g}
        solver = ca.nlpsol("wrist_joint_nlp", "ipopt", nlp, _OPTIONS)
        terms = ca.Function("terms", [x, p], [T, align, ca.norm_2(lateral), -z[2], ca.norm_inf(reach),
                                              ca.norm_2(w_across)])  # fmt: skip
        cache[key] = (solver, terms)
    return cache[key]


def solve_joint_wrist(
    ur5: UR5,
    q0: NDArray[np.float64],
    T_HG: NDArray[np.float64],
    cs_axis: NDArray[np.float64],
    placement_point: NDArray[np.float64],
    points_open: NDArray[np.float64],
    center: NDArray[np.float64],
    closing_axis: NDArray[np.float64],
    up: NDArray[np.float64],
    table_height: float,
    margin: float,
    cone: float = DEFAULT_CONE,
    stand_off: float = 0.0,
    approach_distance: float = 0.10,
    lift: float = 0.15,
) -> JointWristSolution:
    """Solve the NLP (module docstring) from the joints ``q0`` [rad]. Hand-frame data (``cs_axis`` unit,
    ``placement_point``, ``points_open`` (N, 3)) are in the grasp frame; the object's ``center``, unit
    ``closing_axis`` and ``up`` in the world [m]; ``stand_off`` [m] how far before the object's centre along the
    approach the placement point should be (the depth the descent found for the untilted grasp). Success: aligned,
    centred (the CS's part across the up axis at least
    :data:`~softsig_service.planning.wrist_pose.MIN_HORIZONTAL_CS`), within the cone and the limits, with joints
    that also put the flange at the pre-grasp (``approach_distance`` [m] back along the approach) and at the top
    of the lift (``lift`` [m] up)."""
    P = np.asarray(points_open, dtype=np.float64)
    solver, terms = _solver(ur5, len(P))
    params = np.concatenate([
        np.asarray(T_HG, dtype=np.float64).reshape(-1, order="F"), cs_axis, placement_point, center, closing_axis,
        up, [table_height, margin, math.cos(cone), stand_off, approach_distance, lift], P.T.reshape(-1, order="F"),
    ])  # fmt: skip
    lo = np.tile(ur5.lower + LIMIT_MARGIN, 3)
    hi = np.tile(ur5.upper - LIMIT_MARGIN, 3)
    x0 = np.clip(np.tile(np.asarray(q0, dtype=np.float64), 3), lo, hi)
    n_ineq = 1 + len(P)
    lbg = np.r_[np.zeros(n_ineq), np.zeros(12)]
    ubg = np.r_[np.full(n_ineq, np.inf), np.zeros(12)]
    out = solver(x0=x0, p=params, lbx=lo, ubx=hi, lbg=lbg, ubg=ubg)
    stats = solver.stats()
    xs = np.asarray(out["x"], dtype=np.float64).ravel()
    q = xs[:6]
    T, align, lateral, cos_tilt, reach, across = (np.asarray(v, dtype=np.float64) for v in terms(xs, params))
    align_f, lateral_f = float(align.item()), float(lateral.item())
    tilt = math.acos(max(-1.0, min(1.0, float(cos_tilt.item()))))
    ok = (bool(stats.get("success")) and align_f <= ALIGNED and lateral_f <= CENTRED and tilt <= cone + 1e-6
          and float(reach.item()) <= REACHED and float(across.item()) >= MIN_HORIZONTAL_CS)  # fmt: skip
    return JointWristSolution(
        success=ok, status=str(stats.get("return_status", "")), q=q, T_world_grasp=T, tilt=tilt,
        alignment_error=math.asin(math.sqrt(max(align_f, 0.0))), centring_error=lateral_f,
        iterations=int(stats.get("iter_count", 0)),
    )  # fmt: skip
