"""Numeric inverse kinematics of a Pinocchio arm: damped least squares (Levenberg–Marquardt) on the SE(3) error.

The error of a configuration ``q`` [rad] is ``log6(T_fk(q)^-1 T_target)`` (the flange frame's twist to the target,
expressed in the flange frame: linear part [m], angular part [rad]); the step uses the flange's LOCAL frame
Jacobian. Used where the closed form has no answer (a non-UR layout, targets the closed form misses) and to
polish a closed-form seed that is not already exact.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

_EYE6 = np.eye(6)
_POLISHED = 1e-3
"""A start within this fraction of both tolerances is returned as it is (:func:`levenberg_marquardt`)."""


def lm_error(
    model: pin.Model, data: pin.Data, frame_id: int, target: pin.SE3, q: FloatArray
) -> tuple[pin.SE3, FloatArray, float, float, float]:
    """(``T_fk(q)^-1 T_target``, its log6 ``(6,)``, position error [m], rotation error [rad], squared error).

    The errors are sums of scalar squares (as in :func:`settled`, so both report the same numbers to the bit);
    numpy's dot products cost more than the forward kinematics on 3-vectors."""
    pin.forwardKinematics(model, data, q)
    iMd = pin.updateFramePlacement(model, data, frame_id).actInv(target)
    e = np.asarray(pin.log6(iMd).vector)
    v0, v1, v2, w0, w1, w2 = e.tolist()
    t0, t1, t2 = iMd.translation.tolist()
    pe = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    re = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    return iMd, e, pe, re, v0 * v0 + v1 * v1 + v2 * v2 + w0 * w0 + w1 * w1 + w2 * w2


def settled(
    model: pin.Model, data: pin.Data, frame_id: int, target: pin.SE3, q: FloatArray, tol_p: float, tol_r: float
) -> tuple[float, float] | None:
    """(position error [m], rotation error [rad]) of ``q`` [rad] when :func:`levenberg_marquardt` would return it
    unchanged after 0 iterations (within ``_POLISHED`` of the tolerances ``tol_p`` [m], ``tol_r`` [rad]); else
    None. One forward kinematics; the errors are :func:`lm_error`'s, computed the same way."""
    pin.forwardKinematics(model, data, q)
    iMd = pin.updateFramePlacement(model, data, frame_id).actInv(target)
    t0, t1, t2 = iMd.translation.tolist()
    pe = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    if pe > _POLISHED * tol_p:
        return None
    _, _, _, w0, w1, w2 = pin.log6(iMd).vector.tolist()
    re = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    return (pe, re) if re <= _POLISHED * tol_r else None


def levenberg_marquardt(
    model: pin.Model,
    data: pin.Data,
    frame_id: int,
    target: pin.SE3,
    q0: FloatArray,
    max_iterations: int,
    tol_p: float,
    tol_r: float,
) -> tuple[FloatArray, float, float, int, bool]:
    """One damped least-squares run from ``q0`` [rad] towards ``target`` (``T_world_frame``).

    A start already within ``1e-3`` of the tolerances returns at once (0 iterations, ``q0`` unchanged).
    Returns (q [rad], position error [m], rotation error [rad], iterations, converged within ``tol_p`` [m] and
    ``tol_r`` [rad]).
    """
    q = q0.copy()
    iMd, e, pe, re, cost = lm_error(model, data, frame_id, target, q)
    lam = 1e-3
    it = 0
    polish = 2  # once within tolerance, up to two more Newton steps towards 1e-3 of it
    while it < max_iterations:
        if pe <= tol_p and re <= tol_r:
            if polish == 0 or (pe <= _POLISHED * tol_p and re <= _POLISHED * tol_r):
                return q, pe, re, it, True
            polish -= 1
        it += 1
        # J is d(log6(T_fk^-1 T_target))/dq; computeFrameJacobian also refreshes the kinematics at q.
        J = pin.computeFrameJacobian(model, data, q, frame_id, pin.ReferenceFrame.LOCAL)
        Je = -pin.Jlog6(iMd.inverse()) @ J
        JtJ = Je.T @ Je
        g = Je.T @ e
        accepted = False
        improvement = 0.0
        while lam < 1e8:
            dq = -np.linalg.solve(JtJ + lam * (_EYE6 + np.diag(np.diag(JtJ))), g)
            q_new = q + dq
            iMd_n, e_n, pe_n, re_n, cost_n = lm_error(model, data, frame_id, target, q_new)
            if cost_n < cost:
                q, iMd, e, pe, re = q_new, iMd_n, e_n, pe_n, re_n
                lam = max(lam / 10.0, 1e-9)
                accepted = True
                improvement = cost - cost_n
                cost = cost_n
                break
            lam *= 10.0
        if not accepted:
            break  # local minimum: no damped step lowers the error
        if improvement < 1e-14 * max(cost, 1e-30) and float(np.linalg.norm(dq)) < 1e-12:
            break
    ok = pe <= tol_p and re <= tol_r
    return q, pe, re, it, ok
