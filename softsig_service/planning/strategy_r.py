"""Strategy R: the relative pose of the hand that keeps the object capturable under the pose uncertainty it is told.

The object's true pose differs from the nominal one by a yaw ``N(0, sigma_r^2)`` [rad] and a shift
``N(0, sigma_t^2)`` [m] in x and y (docs/design.md §7). With the hand's capture model
(:mod:`softsig_service.signatures.capture`: probability of a carried object per relative pose
``(theta, u, v)``), R chooses the relative pose that maximises the expected capture probability, i.e. the
probability that the perturbed object lies in the capture region:

    maximise  E[P(theta + d_yaw, u + d_u, v + d_v)] - eps * ((theta - theta_C)^2 + (u^2 + v^2) / L^2)

over ``theta`` in one period around C's relative yaw ``theta_C`` and ``u``, ``v`` within the model's grid, with
CasADi (IPOPT) on a B-spline of the expectation (the capture model convolved with the noise on a finer grid, so
the objective is smooth). The small pull ``eps`` toward C's relative pose (and zero offset) breaks ties: where the
expected capture is flat, R takes C's pose; with zero sigmas and a capture region symmetric about C's pose, R is
C. Every local solve starts from the best grid point and from C's pose; the better optimum wins.

Then R's hand poses (:func:`~softsig_service.planning.strategies.relative_poses`) go through the same descent, IK,
approach and collision checks as S and C (:mod:`softsig_service.planning.planner`).

Coordinates: world = UR5 ``base_link``; relative pose as in :mod:`softsig_service.signatures.capture`.
"""

from __future__ import annotations

import hashlib
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from softsig_service.signatures.capture import THETA_PERIOD, CaptureModel, wrap_theta

TIE_WEIGHT = 1e-3
"""``eps``: the pull toward C's relative pose (dimensionless, against probabilities in [0, 1])."""
OFFSET_SCALE = 0.02
"""``L`` [m]: the offset that costs as much as one radian of yaw in the pull."""


def c_relative_theta(cs_axis: NDArray[np.float64], closing: str = "minor") -> float:
    """C's relative yaw [rad]: the theta at which the horizontal part of the closure signature ``cs_axis`` (hand
    frame) lies along the object's minor axis (``closing="minor"``) or major axis, wrapped into [-pi/2, pi/2)."""
    # with hand +z down, hand +y is world +z x hand +x turned by a half turn: angles of hand-frame directions
    # seen from above run clockwise, so the CS's world angle is yaw - atan2(u_y, u_x)
    beta = math.atan2(float(cs_axis[1]), float(cs_axis[0]))
    # CS along o2 (o1 + pi/2): yaw - beta = o1 + pi/2, and theta = o1 - yaw
    shift = math.pi / 2 if closing == "minor" else 0.0
    return float(wrap_theta(-beta - shift))


@dataclass(frozen=True)
class RChoice:
    """R's relative pose: ``theta`` [rad], ``u``, ``v`` [m]; ``expected`` the expected capture probability there
    (in [0, 1]); ``status`` the solver's; ``iterations`` its iterations."""

    theta: float
    u: float
    v: float
    expected: float
    status: str
    iterations: int


def _digest(model: CaptureModel) -> str:
    """A content key of the model's grid and values."""
    h = hashlib.sha256()
    for a in (model.theta, model.u, model.v, model.values):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _degree(samples: NDArray[np.float64]) -> int:
    """Cubic where there are enough samples (a B-spline of degree d needs d + 1 control points)."""
    return min(3, len(samples) - 1)


def _clamped_knots(samples: NDArray[np.float64]) -> list[float]:
    """Knots of a clamped B-spline of degree :func:`_degree` with one control point per sample, spanning them."""
    n, d = len(samples), _degree(samples)
    inner = np.linspace(samples[0], samples[-1], n - d + 1)
    return [float(samples[0])] * d + inner.tolist() + [float(samples[-1])] * d


_LOCAL = threading.local()
PROBLEMS_PER_THREAD = 16
"""Surrogate solvers a thread keeps (least recently used first out)."""


def _solver(model: CaptureModel, sigma_r: float, sigma_t: float) -> ca.Function:
    """This thread's NLP solver on the B-spline surrogate of ``model``'s expected capture under the noise (built on
    first use in each thread). A CasADi solver is not re-entrant (its ``stats()`` are those of the last call made
    with it), so threads never share one, as for C's solvers (:mod:`softsig_service.planning.wrist_pose`)."""
    cache: OrderedDict[tuple[str, float, float], ca.Function] | None = getattr(_LOCAL, "problems", None)
    if cache is None:
        cache = _LOCAL.problems = OrderedDict()
    key = (_digest(model), sigma_r, sigma_t)
    solver = cache.get(key)
    if solver is None:
        solver = cache[key] = _build_solver(model.blurred(sigma_r, sigma_t))
        while len(cache) > PROBLEMS_PER_THREAD:
            cache.popitem(last=False)
    cache.move_to_end(key)
    return solver


def _build_solver(blurred: CaptureModel) -> ca.Function:
    """IPOPT on a B-spline of the noise-averaged model ``blurred``, over three periods of theta; parameter: C's
    relative yaw."""
    # the surrogate on at most ~SURROGATE_POINTS knots per axis (IPOPT's starting points and answers are judged
    # on the model itself, so the surrogate only has to point the way)
    st, su, sv = (max(1, math.ceil(len(a) / SURROGATE_POINTS)) for a in (blurred.theta, blurred.u, blurred.v))
    th, uu, vv = blurred.theta[::st], blurred.u[::su], blurred.v[::sv]
    E = blurred.values[::st, ::su, ::sv]
    th3 = np.concatenate([th - THETA_PERIOD, th, th + THETA_PERIOD])
    E3 = np.concatenate([E] * 3, axis=0)
    # a B-spline whose control points are the samples (a smoothing approximation, built without a fit)
    knots = [_clamped_knots(a) for a in (th3, uu, vv)]
    degrees = [_degree(a) for a in (th3, uu, vv)]
    surrogate = ca.Function.bspline("capture", knots, E3.ravel(order="F").tolist(), degrees, 1, {})
    x = ca.MX.sym("x", 3)
    p = ca.MX.sym("p", 1)  # theta_C
    f = -surrogate(x) + TIE_WEIGHT * ((x[0] - p[0]) ** 2 + (x[1] ** 2 + x[2] ** 2) / OFFSET_SCALE**2)
    nlp: dict[str, Any] = {"x": x, "p": p, "f": f}
    options: dict[str, Any] = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False, "ipopt.max_iter": 200}
    return ca.nlpsol("strategy_r", "ipopt", nlp, options)


SURROGATE_POINTS = 40
"""Knots per axis of the B-spline surrogate at most (one period of theta)."""
REFINE = 4
"""The search grid is the model's grid refined this many times along each axis."""


def solve_strategy_r(model: CaptureModel, sigma_r: float, sigma_t: float, theta_c: float) -> RChoice:
    """R's relative pose for the capture ``model`` under noise ``sigma_r`` [rad], ``sigma_t`` [m] (module
    docstring); ``theta_c`` [rad] is C's relative yaw (:func:`c_relative_theta`).

    Candidates: C's pose, the best point of a search grid (the model's grid refined :data:`REFINE` times, on
    the interpolated expectation), and IPOPT's optima on the smooth surrogate started from both. Each is judged
    by the objective with the model's own expected capture (quadrature at that point); the best wins."""
    theta_c = float(wrap_theta(theta_c))
    sigma_r, sigma_t = float(sigma_r), float(sigma_t)
    blurred = model.blurred(sigma_r, sigma_t)  # cached on the model: computed once per sigmas
    solver = _solver(model, sigma_r, sigma_t)

    def objective(t: float, u: float, v: float) -> tuple[float, float]:
        e = float(model.expected(t, u, v, sigma_r, sigma_t))
        return -e + TIE_WEIGHT * ((t - theta_c) ** 2 + (u * u + v * v) / OFFSET_SCALE**2), e

    n_t = len(model.theta) * REFINE
    ts = theta_c + THETA_PERIOD * (np.arange(n_t) / n_t - 0.5)
    us = np.linspace(model.u[0], model.u[-1], (len(model.u) - 1) * REFINE + 1)
    vs = np.linspace(model.v[0], model.v[-1], (len(model.v) - 1) * REFINE + 1)
    T, U, V = np.meshgrid(ts, us, vs, indexing="ij")
    grid_f = -blurred.probability(T, U, V) + TIE_WEIGHT * ((T - theta_c) ** 2 + (U**2 + V**2) / OFFSET_SCALE**2)
    i = np.unravel_index(int(np.argmin(grid_f)), grid_f.shape)
    starts = [(theta_c, 0.0, 0.0, "c_pose", 0), (float(T[i]), float(U[i]), float(V[i]), "grid", 0)]
    lbx = [theta_c - THETA_PERIOD / 2, float(model.u[0]), float(model.v[0])]
    ubx = [theta_c + THETA_PERIOD / 2, float(model.u[-1]), float(model.v[-1])]
    candidates = list(starts)
    for t0, u0, v0, _, _ in starts:
        sol = solver(x0=[t0, u0, v0], p=[theta_c], lbx=lbx, ubx=ubx)
        stats = solver.stats()
        w = np.asarray(sol["x"]).ravel()
        candidates.append((float(w[0]), float(w[1]), float(w[2]), str(stats.get("return_status", "")),
                           int(stats.get("iter_count", 0))))  # fmt: skip
    best: RChoice | None = None
    best_f = math.inf
    for t, u, v, status, iterations in candidates:
        f, e = objective(t, u, v)
        if f < best_f - 1e-12:
            best_f = f
            best = RChoice(float(wrap_theta(t)), u, v, e, status, iterations)
    assert best is not None
    return best
