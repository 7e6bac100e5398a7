"""Strategy C's wrist-pose optimisation (CasADi NLP, solved with Ipopt), built once per number of points.

Decision variables: the hand (flange, = UR5 ``tool0``) pose in the world (UR5 ``base_link``, z up) as
position ``t = (x, y, z)`` [m], ``yaw`` about world z and small ``roll``/``pitch`` [rad]. The hand's
orientation is ``R = Rz(yaw) · Rx(pi + roll) · Ry(pitch)``: with roll = pitch = 0, hand +z points down (a top
grasp) and hand +x keeps its heading ``yaw``.

The hand point put over the object's centre is the *placement point* ``p_a`` [m, hand frame], passed as
``placement_point``. The planner (:mod:`softsig_service.planning.planner`) passes
``HandPlanningModel.placement_point("C", PlanRequest.placement)``: by default (``placement="open_centre"``) the
centre c_0 of the open hand's reference-point ellipsoid (MVEE; the ellipsoid CS's anchor, whatever CS method is
used); with ``"grasp_centre"`` the centre c_T of the closed hand's reference-point ellipsoid; with ``"per_strategy"``
the CS's own anchor (c_0 for the ellipsoid method; the centroid of the open reference points for pca, of the
open hand's surface points for mesh). With ``"open_centre"`` and ``"grasp_centre"`` strategy S puts the same
point there (docs/design.md §6).

Cost (all terms dimensionless or scaled by a stated length):

* alignment: ``sin^2`` of the angle between the horizontal projection of the closure signature axis
  ``R u`` and the object's closing axis ``a`` (an axis: both signs align);
* centring: squared horizontal distance of the placement point ``t + R p_a`` from the object's centre, per
  ``CENTRING_SCALE`` [m], weighted 1e-3;
* depth: squared height of the placement point above the object's centre, per ``DEPTH_SCALE`` [m], weighted
  1e-3;
* tilt: ``roll^2 + pitch^2`` weighted by ``TILT_WEIGHT``.

Constraints: every reference point of the open hand at least ``margin`` [m] above the table plane; roll and
pitch within +-``MAX_TILT``; the flange within the UR5's reach shell around its shoulder. Object data enter as
parameters, so the compiled solver is reused for every object and pose.

Every term of the cost is non-negative, and the untilted pose that aligns the CS, puts the placement point on
the object's centre and keeps the depth at zero makes each of them zero. Where that closed-form pose satisfies
the constraints it is therefore a global minimum: the cost and constraints (the compiled NLP's expressions, in
numpy) are evaluated there once (status ``closed_form``, 0 iterations) and no iteration is run. Otherwise (the
table keeps the hand above the object's centre, or the shoulder's shell is in the way) the NLP is solved by SQP
(qrqp) from that pose raised by 0.1 mm, with Ipopt as the fallback.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput

CENTRING_SCALE = 0.01
DEPTH_SCALE = 0.05
TILT_WEIGHT = 0.5
MAX_TILT = 0.2
"""Largest roll/pitch [rad] the optimisation may use."""
SHOULDER = (0.0, 0.0, 0.089159)
"""UR5 shoulder centre in base_link [m] (DH d1)."""
REACH = (0.20, 0.85)
"""Inner and outer radius [m] of the flange's reachable shell around the shoulder."""
CENTRING_TOLERANCE = 0.002
"""[m] a solution whose placement point misses the object's centre by more than this is not a grasp (unreachable)."""
MIN_HORIZONTAL_CS = 0.2
"""Below this horizontal norm of the CS axis (hand pointing down) the alignment is impossible."""

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class WristPoseSolution:
    """One solution of the wrist-pose NLP; ``T_world_hand`` is the flange pose in the world [m, rad]."""

    success: bool
    status: str
    T_world_hand: NDArray[np.float64]
    yaw: float
    roll: float
    pitch: float
    alignment_error: float
    """Angle [rad] between the CS's horizontal projection and the closing axis (as lines)."""
    centring_error: float
    """Horizontal distance [m] of the placement point ``t + R p_a`` from the object's centre."""
    clearance: float
    """Lowest open-hand reference point's height above the table [m]."""
    iterations: int
    solve_time: float
    """[s] this branch's solve (its closed-form check included)."""


def hand_rotation(yaw: Any, roll: Any, pitch: Any, lib: Any = np) -> Any:
    """``Rz(yaw) Rx(pi + roll) Ry(pitch)`` with numpy (angles [rad] as floats; the product written out) or casadi
    (``lib``; symbols)."""
    if lib is np:
        cz, sz = math.cos(yaw), math.sin(yaw)
        cr, sr = -math.cos(roll), -math.sin(roll)  # cos/sin of pi + roll
        cp, sp = math.cos(pitch), math.sin(pitch)
        return np.array(
            [
                [cz * cp - sz * sr * sp, -sz * cr, cz * sp + sz * sr * cp],
                [sz * cp + cz * sr * sp, cz * cr, sz * sp - cz * sr * cp],
                [-cr * sp, sr, cr * cp],
            ]
        )
    cz, sz = lib.cos(yaw), lib.sin(yaw)
    cr, sr = -lib.cos(roll), -lib.sin(roll)
    cp, sp = lib.cos(pitch), lib.sin(pitch)
    Rz = ca.vertcat(ca.horzcat(cz, -sz, 0), ca.horzcat(sz, cz, 0), ca.horzcat(0, 0, 1))
    Rx = ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, cr, -sr), ca.horzcat(0, sr, cr))
    Ry = ca.vertcat(ca.horzcat(cp, 0, sp), ca.horzcat(0, 1, 0), ca.horzcat(-sp, 0, cp))
    return Rz @ Rx @ Ry


_SQP_OPTIONS: dict[str, Any] = {
    "qpsol": "qrqp",
    "qpsol_options": {"print_iter": False, "print_header": False, "error_on_fail": False},
    "print_time": False, "print_header": False, "print_iteration": False, "print_status": False,
    "max_iter": 100, "tol_pr": 1e-10, "tol_du": 1e-10,
}  # fmt: skip
"""SQP with CasADi's qrqp: from the closed-form initial guess it converges in a few iterations (~0.25 ms)."""
_IPOPT_OPTIONS: dict[str, Any] = {
    "ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": 1e-10,
    "ipopt.max_iter": 200, "ipopt.mu_strategy": "adaptive",
}  # fmt: skip
"""Ipopt (interior point): the fallback when the SQP does not converge."""


_LOCAL = threading.local()


CLOSED_FORM_COST = 1e-18
"""The closed-form pose is taken as the minimum when its cost is at most this (zero up to rounding: an alignment
error of 1e-9 rad costs 1e-18) and it satisfies every constraint."""
_RAISE = 1e-4
"""[m] the SQP starts this far above the closed-form pose (off the table constraint's boundary)."""


def _solver(n_points: int, method: str = "sqpmethod") -> tuple[ca.Function, int]:
    """This thread's compiled solver for ``n_points`` reference points (built on first use in each thread).

    A CasADi solver is not re-entrant (its ``stats()`` are those of the last call made with it), so threads never
    share one: the service's threads plan in parallel without a lock around the NLP.
    """
    cache: dict[tuple[int, str], tuple[ca.Function, int]] | None = getattr(_LOCAL, "solvers", None)
    if cache is None:
        cache = _LOCAL.solvers = {}
    hit = cache.get((n_points, method))
    if hit is None:
        hit = cache[(n_points, method)] = _build_solver(n_points, method)
    return hit


def _cost_and_constraints(w: Any, R: Any, u: Any, pa: Any, Pz: Any, c: Any, a: Any, table: Any, margin: Any) -> Any:
    """The NLP's cost ``f`` and constraints ``g`` (n heights [m], then the squared reach [m^2]) at ``w`` = (x, y,
    z, yaw, roll, pitch) with ``R`` = :func:`hand_rotation` of its angles and ``Pz`` the world z offsets [m] of the
    reference points (``(R P)[2, :]``, one per point): one formula for CasADi symbols (the compiled NLP) and for
    numpy floats (the closed-form check). Returns ``(f, heights, reach)``."""
    t = w[0:3]
    v = R @ u
    cross = v[0] * a[1] - v[1] * a[0]
    align = cross**2 / (v[0] ** 2 + v[1] ** 2 + 1e-9)
    anchor = t + R @ pa
    centring = ((anchor[0] - c[0]) ** 2 + (anchor[1] - c[1]) ** 2) / CENTRING_SCALE**2
    depth = (anchor[2] - c[2]) ** 2 / DEPTH_SCALE**2
    tilt = TILT_WEIGHT * (w[4] ** 2 + w[5] ** 2)
    heights = t[2] + Pz - table - margin  # >= 0
    s = (t[0] - SHOULDER[0], t[1] - SHOULDER[1], t[2] - SHOULDER[2])
    reach = s[0] ** 2 + s[1] ** 2 + s[2] ** 2
    f = align + 1e-3 * (centring + depth) + tilt
    return f, heights, reach


def _build_solver(n_points: int, method: str) -> tuple[ca.Function, int]:
    """The wrist-pose NLP for ``n_points`` reference points, compiled with ``method`` (sqpmethod or ipopt)."""
    w = ca.SX.sym("w", 6)  # x, y, z, yaw, roll, pitch
    p = ca.SX.sym("p", 3 + 3 + 3 * n_points + 3 + 2 + 2)
    u, pa = p[0:3], p[3:6]
    P = ca.reshape(p[6 : 6 + 3 * n_points], 3, n_points)
    k = 6 + 3 * n_points
    c, a, table, margin = p[k : k + 3], p[k + 3 : k + 5], p[k + 5], p[k + 6]
    R = hand_rotation(w[3], w[4], w[5], lib=ca)
    f, heights, reach = _cost_and_constraints(w, R, u, pa, (R @ P)[2, :].T, c, a, table, margin)
    nlp = {"x": w, "p": p, "f": f, "g": ca.vertcat(heights, reach)}
    opts = _SQP_OPTIONS if method == "sqpmethod" else _IPOPT_OPTIONS
    return ca.nlpsol("wrist_pose", method, nlp, opts), n_points


def _closed_form(v0: NDArray[np.float64], pa: NDArray[np.float64], P: NDArray[np.float64],
                 c: NDArray[np.float64], a: NDArray[np.float64], table: float, margin: float,
                 yaw_offset: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:  # fmt: skip
    """The untilted pose ``(x, y, z, yaw, 0, 0)`` that aligns the CS (``v0``: at yaw 0) with ``a``, puts the
    placement point over ``c`` and at its height, or as low as the table lets the reference points go; and its
    rotation."""
    yaw = math.atan2(a[1], a[0]) - math.atan2(v0[1], v0[0]) + yaw_offset
    R = hand_rotation(yaw, 0.0, 0.0)
    t = c - R @ pa
    t[2] = max(c[2] - (R @ pa)[2], table + margin - float((P @ R.T)[:, 2].min()))
    return np.array([t[0], t[1], t[2], yaw, 0.0, 0.0]), R


def _satisfies(g: NDArray[np.float64], n: int, slack: float = 0.0) -> bool:
    """Whether the constraint values ``g`` (n heights [m], then the squared reach [m^2]) lie within their bounds,
    each widened by ``slack``."""
    return bool(g[:n].min() >= -slack and REACH[0] ** 2 - slack <= g[n] <= REACH[1] ** 2 + slack)


def solve_wrist_pose(
    cs_axis: NDArray[np.float64],
    placement_point: NDArray[np.float64],
    points_open: NDArray[np.float64],
    object_center: NDArray[np.float64],
    closing_axis: NDArray[np.float64],
    *,
    table_height: float = 0.0,
    margin: float = 0.005,
) -> list[WristPoseSolution]:
    """Solve strategy C for both yaw branches of the CS axis; return the two solutions (best first).

    ``cs_axis`` (unit) and ``placement_point`` [m] and ``points_open`` (N, 3) [m] are in the hand frame;
    ``object_center`` [m] and the horizontal ``closing_axis`` (2 or 3 components, unit after projection) are in
    the world frame. ``placement_point`` is the placement point p_a that is put over
    ``object_center``, not necessarily the CS's anchor: the planner passes
    ``HandPlanningModel.placement_point("C", placement)`` (default c_0, the open hand's reference-point
    ellipsoid centre; see the module docstring).
    """
    u = np.asarray(cs_axis, dtype=float).reshape(3)
    pa = np.asarray(placement_point, dtype=float).reshape(3)
    P = np.asarray(points_open, dtype=float).reshape(-1, 3)
    c = np.asarray(object_center, dtype=float).reshape(3)
    a = np.asarray(closing_axis, dtype=float).ravel()[:2]
    for name, arr in (("cs_axis", u), ("placement_point", pa), ("points_open", P), ("object_center", c),
                      ("closing_axis", a)):  # fmt: skip
        if not np.all(np.isfinite(arr)):
            raise InvalidInput("values must be finite", field=name)
    if np.linalg.norm(a) < 1e-9:
        raise InvalidInput("closing axis has no horizontal component", field="closing_axis")
    return solve_wrist_pose_unchecked(u, pa, P, c, a, table_height, margin)


def solve_wrist_pose_unchecked(
    u: FloatArray, pa: FloatArray, P: FloatArray, c: FloatArray, a: FloatArray, table_height: float, margin: float
) -> list[WristPoseSolution]:
    """:func:`solve_wrist_pose` for callers that pass checked values: ``u`` ``(3,)``, ``pa`` ``(3,)`` [m], ``P``
    ``(N, 3)`` [m] (hand frame), ``c`` ``(3,)`` [m] and ``a`` (2 or 3 components with a horizontal part, world
    frame), all finite float arrays; ``table_height`` and ``margin`` [m] as there. Nothing is validated again."""
    a = np.asarray(a, dtype=float).ravel()[:2]
    a = a / math.sqrt(float(a @ a))
    u = u / math.sqrt(float(u @ u))
    horizontal = math.hypot(u[0], u[1])
    solver, n = _solver(len(P))
    params = np.concatenate([u, pa, P.reshape(-1), c, a, [table_height, margin]])
    lbx = [-ca.inf, -ca.inf, -ca.inf, -ca.inf, -MAX_TILT, -MAX_TILT]
    ubx = [ca.inf, ca.inf, ca.inf, ca.inf, MAX_TILT, MAX_TILT]
    lbg = [0.0] * n + [REACH[0] ** 2]
    ubg = [ca.inf] * n + [REACH[1] ** 2]
    v0 = hand_rotation(0.0, 0.0, 0.0) @ u
    out = []
    for offset in (0.0, math.pi):
        t0 = time.perf_counter()
        w, R = _closed_form(v0, pa, P, c, a, table_height, margin, offset)
        f, heights, reach = _cost_and_constraints(w, R, u, pa, P @ R[2], c, a, table_height, margin)
        g = np.append(heights, reach)
        stats: dict[str, Any] = {"success": True, "return_status": "closed_form", "iter_count": 0}
        if not (f <= CLOSED_FORM_COST and _satisfies(g, n)):
            x0 = w.copy()
            x0[2] += _RAISE
            sol = solver(x0=x0, p=params, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
            stats = solver.stats()
            if not stats.get("success", False):
                fallback, _ = _solver(len(P), "ipopt")
                sol = fallback(x0=x0, p=params, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
                stats = fallback.stats()
            w, g = sol["x"].full().ravel(), sol["g"].full().ravel()
            R = hand_rotation(w[3], w[4], w[5])
        elapsed = time.perf_counter() - t0
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, w[:3]
        v = R @ u
        err = math.asin(min(1.0, abs(v[0] * a[1] - v[1] * a[0]) / max(math.hypot(v[0], v[1]), 1e-12)))
        anchor = w[:3] + R @ pa
        feasible = _satisfies(g, n, slack=1e-6)
        status = str(stats.get("return_status", ""))
        centring = math.hypot(anchor[0] - c[0], anchor[1] - c[1])
        feasible = feasible and centring <= CENTRING_TOLERANCE
        ok = bool(stats.get("success", False)) and feasible and horizontal >= MIN_HORIZONTAL_CS
        if horizontal < MIN_HORIZONTAL_CS:
            status = "alignment_impossible"
        elif centring > CENTRING_TOLERANCE:
            status = "unreachable"
        elif not feasible:
            status = "unreachable" if not (REACH[0] ** 2 <= g[n] <= REACH[1] ** 2) else "infeasible"
        out.append(
            WristPoseSolution(
                success=ok,
                status=status,
                T_world_hand=T,
                yaw=float(math.remainder(w[3], 2 * math.pi)),
                roll=float(w[4]),
                pitch=float(w[5]),
                alignment_error=float(err),
                centring_error=centring,
                clearance=float(g[:n].min() + margin),
                iterations=int(stats.get("iter_count", 0)),
                solve_time=elapsed,
            )
        )
    return out
