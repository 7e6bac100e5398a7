"""Closed-form inverse kinematics of a UR arm (the UR5's), from its standard DH table.

Frames and units: ``base_link`` of the URDF is the DH base frame turned by pi about z; the flange is ``tool0``.
Poses are 4x4 homogeneous transforms ``T_base_link_tool0`` with positions in [m]; joint positions in [rad].

The eight branches (shoulder left/right x wrist up/down x elbow up/down) come in the order shoulder, wrist,
elbow; each is exact up to rounding, so a numeric solver only has to confirm it. :meth:`URParameters.nearest_branch`
finds the one nearest a reference configuration, wrapped into the joint limits, without working out the others.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

_DH_ALPHA = (math.pi / 2.0, 0.0, 0.0, math.pi / 2.0, -math.pi / 2.0, 0.0)
_RZ_PI = np.diag([-1.0, -1.0, 1.0, 1.0])
"""``base_link`` is the DH base frame turned by pi about z (the URDF's note on ``base``)."""
_ARGUMENT_SLACK = 1e-6
"""A trigonometric argument outside [-1, 1] by more than this drops its branch (closer: clamped)."""
_WRIST_SINGULAR = 1e-10
"""Below this |sin q5| the wrist is singular and q6 is free."""
_PI = math.pi
_TWO_PI = 2.0 * math.pi
_PRUNE = 1.0 + 1e-9
"""A partial squared distance above ``_PRUNE`` times the best full one cannot win, whatever the rounding."""


def wrap_joint(q: float, reference: float, lower: float, upper: float) -> float | None:
    """A closed-form joint value ``q`` [rad] reduced into [-pi, pi) as :meth:`URParameters.ik_array` reduces it,
    then shifted by a multiple of 2 pi to its value within ``[lower, upper]`` [rad] closest to ``reference``
    [rad], exactly as ``UR5._wrap_rows`` does (the same float operations); None when no value fits the limits."""
    q = (q + _PI) % _TWO_PI - _PI
    # the common case first: when the turn nearest the reference lies within the limits, the clamps below do
    # nothing (k_lo <= k <= k_hi holds with their 1e-12 slack) and are skipped; |z| < 1/2 rounds to 0 (no turn)
    z = (reference - q) / _TWO_PI
    w = q if -0.5 < z < 0.5 else q + round(z) * _TWO_PI
    if lower <= w <= upper:
        return w
    k_lo = math.ceil((lower - q) / _TWO_PI - 1e-12)
    k_hi = math.floor((upper - q) / _TWO_PI + 1e-12)
    if k_lo > k_hi:
        return None
    k = min(max(round((reference - q) / _TWO_PI), k_lo), k_hi)
    return min(max(q + k * _TWO_PI, lower), upper)


def _dh_matrix(theta: float, d: float, a: float, alpha: float) -> FloatArray:
    """One DH link transform (4x4) for joint angle ``theta`` [rad], offsets ``d``, ``a`` [m], twist ``alpha``."""
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


@dataclass(frozen=True)
class URParameters:
    """Standard DH lengths [m] of a UR arm: ``a = (0, -a2, -a3, 0, 0, 0)``, ``d = (d1, 0, 0, d4, d5, d6)``,
    ``alpha = (pi/2, 0, 0, pi/2, -pi/2, 0)``. ``T_base_link_tool0(q) = Rz(pi) T_dh(q)``."""

    d1: float
    a2: float
    a3: float
    d4: float
    d5: float
    d6: float

    def fk(self, q: ArrayLike) -> FloatArray:
        """``T_base_link_tool0`` (4x4, [m]) from the DH table at ``q`` [rad]."""
        a = (0.0, -self.a2, -self.a3, 0.0, 0.0, 0.0)
        d = (self.d1, 0.0, 0.0, self.d4, self.d5, self.d6)
        T = _RZ_PI.copy()
        for i, th in enumerate(np.asarray(q, dtype=np.float64)):
            T = T @ _dh_matrix(float(th), d[i], a[i], _DH_ALPHA[i])
        return T

    def ik(self, target: FloatArray, q6_default: float = 0.0) -> list[FloatArray]:
        """Up to 8 closed-form solutions [rad] (in (-pi, pi]) for ``T_base_link_tool0 = target``, as a list
        (see :meth:`ik_array`)."""
        return list(self.ik_array(target, q6_default))

    def ik_array(self, target: FloatArray, q6_default: float = 0.0) -> FloatArray:
        """Closed-form solutions ``(k, 6)`` [rad], k <= 8, each joint in (-pi, pi], for ``T_base_link_tool0 =
        target`` (4x4, [m]); ``(0, 6)`` when the target is out of reach. Rows in the order shoulder, wrist, elbow.

        Branches whose trigonometric arguments leave [-1, 1] by more than 1e-6 are dropped; arguments just
        outside are clamped. At the wrist singularity (sin q5 ~ 0) q6 is free and set to ``q6_default``.
        Scalar arithmetic throughout (a few microseconds; numpy's per-call cost would dominate on 4x4 matrices).
        """
        # Rz(pi) (its own inverse) negates the first two rows
        rows = np.asarray(target, dtype=np.float64)[:3].tolist()
        (R00, R01, R02, px), (R10, R11, R12, py), (R20, R21, R22, pz) = rows
        R00, R01, R02, px, R10, R11, R12, py = -R00, -R01, -R02, -px, -R10, -R11, -R12, -py
        d1, d4, d5, d6 = self.d1, self.d4, self.d5, self.d6
        x05, y05 = px - d6 * R02, py - d6 * R12
        r = math.hypot(x05, y05)
        if r < 1e-12 or abs(d4 / r) > 1.0 + _ARGUMENT_SLACK:
            return np.zeros((0, 6))
        phi = math.acos(max(-1.0, min(1.0, d4 / r)))
        psi = math.atan2(y05, x05)
        L2, L3 = -self.a2, -self.a3
        out: list[tuple[float, ...]] = []
        for q1 in (psi + phi + math.pi / 2.0, psi - phi + math.pi / 2.0):
            s1, c1 = math.sin(q1), math.cos(q1)
            c5 = (px * s1 - py * c1 - d4) / d6
            if abs(c5) > 1.0 + _ARGUMENT_SLACK:
                continue
            a5 = math.acos(max(-1.0, min(1.0, c5)))
            sin_a5, c5 = math.sin(a5), math.cos(a5)  # of -a5: -sin, cos (odd and even, exactly)
            # columns of R turned into the shoulder's frame (frame 1 of the DH table)
            u0, u1, u2 = R00 * c1 + R10 * s1, R01 * c1 + R11 * s1, R02 * c1 + R12 * s1
            n6, m6 = -R01 * s1 + R11 * c1, R00 * s1 - R10 * c1  # sin q5 (sin q6, cos q6)
            for q5, s5 in ((a5, sin_a5), (-a5, -sin_a5)):
                q6 = q6_default if abs(s5) < _WRIST_SINGULAR else math.atan2(n6 / s5, m6 / s5)
                s6, c6 = math.sin(q6), math.cos(q6)
                # T14 = T01^-1 T T56^-1 T45^-1 (planar 2-link): its first column and its translation
                t00 = c5 * (u0 * c6 - u1 * s6) - s5 * u2
                t10 = c5 * (R20 * c6 - R21 * s6) - R22 * s5
                x = px * c1 + py * s1 + d5 * (u0 * s6 + u1 * c6) - d6 * u2
                y = pz - d1 - R22 * d6 + d5 * (R20 * s6 + R21 * c6)
                c3 = (x * x + y * y - L2 * L2 - L3 * L3) / (2.0 * L2 * L3)
                if abs(c3) > 1.0 + _ARGUMENT_SLACK:
                    continue
                a3 = math.acos(max(-1.0, min(1.0, c3)))
                sin_a3, c3 = math.sin(a3), math.cos(a3)
                q234 = math.atan2(t10, t00)
                theta = math.atan2(y, x)
                for q3, s3 in ((a3, sin_a3), (-a3, -sin_a3)):
                    q2 = theta - math.atan2(L3 * s3, L2 + L3 * c3)
                    out.append((q1, q2, q3, q234 - q2 - q3, q5, q6))
        sol = np.array(out, dtype=np.float64).reshape(-1, 6)
        return np.asarray(np.remainder(sol + math.pi, 2.0 * math.pi) - math.pi, dtype=np.float64)

    def nearest_branch(
        self,
        rows: list[list[float]],
        reference: Sequence[float],
        lower: Sequence[float],
        upper: Sequence[float],
    ) -> tuple[float, ...] | None:
        """The closed-form solution [rad] nearest ``reference`` [rad] (Euclidean, in joint space) after wrapping
        each joint into ``[lower, upper]`` [rad] closest to ``reference``; None when no branch fits the limits.

        ``rows`` are the first three rows of ``T_base_link_tool0`` (4x4, [m]) as lists. The answer is the one
        :meth:`ik_array` (with ``q6_default = reference[5]``), ``UR5._wrap_rows`` and a stable sort by distance
        give, to the last bit: the same float operations, the same tie order (shoulder, wrist, elbow). Faster
        because it is a best-first search: a shoulder, wrist or elbow choice whose partial squared distance
        already exceeds the best complete branch is not worked out (with a warm start, one or two branches are),
        and scalar throughout (numpy's per-call cost would dominate on 6-vectors).
        """
        pi, wrap, bound_factor = _PI, wrap_joint, _PRUNE
        (R00, R01, R02, px), (R10, R11, R12, py), (R20, R21, R22, pz) = rows[0], rows[1], rows[2]
        R00, R01, R02, px, R10, R11, R12, py = -R00, -R01, -R02, -px, -R10, -R11, -R12, -py
        r0, r1, r2, r3, r4, r5 = reference
        lo0, lo1, lo2, lo3, lo4, lo5 = lower
        hi0, hi1, hi2, hi3, hi4, hi5 = upper
        d4, d6 = self.d4, self.d6
        x05, y05 = px - d6 * R02, py - d6 * R12
        r = math.hypot(x05, y05)
        if r < 1e-12 or abs(d4 / r) > 1.0 + _ARGUMENT_SLACK:
            return None
        phi = math.acos(max(-1.0, min(1.0, d4 / r)))
        psi = math.atan2(y05, x05)
        L2, L3 = -self.a2, -self.a3
        d1, d5 = self.d1, self.d5
        best: tuple[float, ...] | None = None
        best_dist = best_bound = math.inf
        best_index = 8
        shoulders = []
        for i, q1 in enumerate((psi + phi + pi / 2.0, psi - phi + pi / 2.0)):
            w1 = wrap(q1, r0, lo0, hi0)
            if w1 is None:
                continue
            shoulders.append(((w1 - r0) * (w1 - r0), i, q1, w1))
        if len(shoulders) == 2 and shoulders[1][0] < shoulders[0][0]:
            shoulders.reverse()
        for lb1, i, q1, w1 in shoulders:
            if lb1 > best_bound:
                continue
            s1, c1 = math.sin(q1), math.cos(q1)
            c5 = (px * s1 - py * c1 - d4) / d6
            if abs(c5) > 1.0 + _ARGUMENT_SLACK:
                continue
            a5 = math.acos(max(-1.0, min(1.0, c5)))
            sin_a5, c5 = math.sin(a5), math.cos(a5)
            u0, u1, u2 = R00 * c1 + R10 * s1, R01 * c1 + R11 * s1, R02 * c1 + R12 * s1
            n6, m6 = -R01 * s1 + R11 * c1, R00 * s1 - R10 * c1
            wrists = []
            for j, q5, s5 in ((0, a5, sin_a5), (1, -a5, -sin_a5)):
                w5 = wrap(q5, r4, lo4, hi4)
                if w5 is None:
                    continue
                wrists.append((lb1 + (w5 - r4) * (w5 - r4), j, s5, w5))
            if len(wrists) == 2 and wrists[1][0] < wrists[0][0]:
                wrists.reverse()
            for lb5, j, s5, w5 in wrists:
                if lb5 > best_bound:
                    continue
                q6 = r5 if abs(s5) < _WRIST_SINGULAR else math.atan2(n6 / s5, m6 / s5)
                w6 = wrap(q6, r5, lo5, hi5)
                if w6 is None:
                    continue
                lb2 = lb5 + (w6 - r5) * (w6 - r5)
                if lb2 > best_bound:
                    continue
                s6, c6 = math.sin(q6), math.cos(q6)
                # T14 = T01^-1 T T56^-1 T45^-1 (planar 2-link): its first column and its translation
                t00 = c5 * (u0 * c6 - u1 * s6) - s5 * u2
                t10 = c5 * (R20 * c6 - R21 * s6) - R22 * s5
                x = px * c1 + py * s1 + d5 * (u0 * s6 + u1 * c6) - d6 * u2
                y = pz - d1 - R22 * d6 + d5 * (R20 * s6 + R21 * c6)
                c3 = (x * x + y * y - L2 * L2 - L3 * L3) / (2.0 * L2 * L3)
                if abs(c3) > 1.0 + _ARGUMENT_SLACK:
                    continue
                a3 = math.acos(max(-1.0, min(1.0, c3)))
                sin_a3, c3 = math.sin(a3), math.cos(a3)
                elbows = []
                for k, q3, s3 in ((0, a3, sin_a3), (1, -a3, -sin_a3)):
                    w3 = wrap(q3, r2, lo2, hi2)
                    if w3 is None:
                        continue
                    elbows.append((lb2 + (w3 - r2) * (w3 - r2), k, q3, s3, w3))
                if len(elbows) == 2 and elbows[1][0] < elbows[0][0]:
                    elbows.reverse()
                q234 = math.atan2(t10, t00)
                theta = math.atan2(y, x)
                for lb3, k, q3, s3, w3 in elbows:
                    if lb3 > best_bound:
                        continue
                    q2 = theta - math.atan2(L3 * s3, L2 + L3 * c3)
                    w2 = wrap(q2, r1, lo1, hi1)
                    if w2 is None:
                        continue
                    q4 = q234 - q2 - q3
                    w4 = wrap(q4, r3, lo3, hi3)
                    if w4 is None:
                        continue
                    e0, e1, e2, e3, e4, e5 = w1 - r0, w2 - r1, w3 - r2, w4 - r3, w5 - r4, w6 - r5
                    full = e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3 + e4 * e4 + e5 * e5
                    dist, index = math.sqrt(full), 4 * i + 2 * j + k
                    if dist < best_dist or (dist == best_dist and index < best_index):
                        best, best_dist, best_index = (w1, w2, w3, w4, w5, w6), dist, index
                        best_bound = full * bound_factor
        return best


def ur_parameters(model: pin.Model, data: pin.Data, flange_frame_id: int) -> URParameters | None:
    """DH lengths read off the model at q = 0 and checked against Pinocchio's FK at 10 random configurations;
    None if they disagree (then only the numeric solver is used)."""
    q0 = np.zeros(model.nq)
    pin.forwardKinematics(model, data, q0)
    o = [np.array(data.oMi[j].translation) for j in range(model.njoints)]
    tool = np.array(pin.updateFramePlacement(model, data, flange_frame_id).translation)
    params = URParameters(
        d1=float(o[1][2]),
        a2=float(abs(o[3][0] - o[2][0])),
        a3=float(abs(o[4][0] - o[3][0])),
        d4=float(o[5][1]),
        d5=float(o[5][2] - o[6][2]),
        d6=float(tool[1] - o[6][1]),
    )
    rng = np.random.default_rng(1234)
    for _ in range(10):
        q = rng.uniform(-math.pi, math.pi, model.nq)
        pin.forwardKinematics(model, data, q)
        T = np.array(pin.updateFramePlacement(model, data, flange_frame_id).homogeneous)
        if not np.allclose(params.fk(q), T, atol=1e-9):
            return None
    return params
