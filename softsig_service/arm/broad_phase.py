"""Broad phase of the arm's collision checks: bounding volumes that rule pairs out before coal is asked.

Every geometry of a Pinocchio ``GeometryModel`` gets two bounding volumes built from coal's local AABB (in the
geometry's own frame): the oriented box of that AABB (OBB, carried by the geometry's placement and its parent
joint) and the sphere around it (the AABB's centre and half-diagonal ``aabb_radius``) [m]. A half-space (the
table, ``z <= h`` in the world frame) has neither: a pair with it is bounded by the OBB's lowest point.

At a configuration, the spheres rule out most pairs with a few vector operations; the pairs that remain are
tested box against box with the separating-axis theorem (15 axes), the first box grown by the pair's security
margin on every side (a superset of all points within the margin). A pair that passes neither test cannot
collide; the others are handed to coal exactly as before, so the verdicts do not change.

Frames and units: world = UR5 ``base_link`` (z up); lengths in [m]; joint positions in [rad].
"""

from __future__ import annotations

from collections.abc import Sequence

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from softsig_service.arm.shapes import local_aabb

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

_SLACK = 1e-9
"""[m] added to every margin so that rounding in the bounds never drops a pair that touches."""
_PARALLEL = 1e-9
"""Added to |R| in the separating-axis test so that near-parallel edges give no false separation."""
_NEXT = np.array([1, 2, 0])
_AFTER = np.array([2, 0, 1])


class BroadPhase:
    """Bounding volumes of the geometries of ``gm`` and the test that keeps the pairs that may collide.

    Args:
        gm: the geometry model (every object's ``placement`` is in its parent joint's frame).
        halfspace: index of the table's half-space geometry in ``gm`` (normal +z, offset ``height`` [m]).
        height: z [m] of the half-space's plane in the world.
    """

    def __init__(self, gm: pin.GeometryModel, halfspace: int, height: float) -> None:
        n = len(gm.geometryObjects)
        self.parent = np.zeros(n, dtype=np.intp)
        self.local_rotation = np.tile(np.eye(3), (n, 1, 1))
        self.local_centre = np.zeros((n, 3))
        self.half = np.zeros((n, 3))
        self.radius = np.zeros(n)
        for i, go in enumerate(gm.geometryObjects):
            self.parent[i] = int(go.parentJoint)
            if i != halfspace:
                self._set(i, go.placement, go.geometry)
        self.halfspace = halfspace
        self.height = height
        self._joints = [int(j) for j in np.unique(self.parent) if j]

    def _set(self, index: int, placement: pin.SE3, geometry: coal.CollisionGeometry) -> None:
        box = local_aabb(geometry).aabb_local
        lo, hi = np.asarray(box.min_), np.asarray(box.max_)
        self.local_rotation[index] = placement.rotation
        self.local_centre[index] = placement.act(0.5 * (lo + hi))
        self.half[index] = 0.5 * (hi - lo)
        self.radius[index] = float(np.linalg.norm(self.half[index]))

    def move(self, index: int, placement: pin.SE3, geometry: coal.CollisionGeometry) -> None:
        """Update the volumes of geometry ``index`` after its ``placement`` (in its parent joint) changed."""
        self._set(index, placement, geometry)

    def joint_placements(self, model: pin.Model, data: pin.Data, Q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Forward kinematics at each row of ``Q`` ``(W, nq)`` [rad]: the joints' world rotations ``(W, J, 3, 3)``
        and translations ``(W, J, 3)`` [m] (J = ``model.njoints``; joint 0 is the world). ``data`` is left at the
        last row."""
        W, J = len(Q), model.njoints
        R = np.tile(np.eye(3), (W, J, 1, 1))
        t = np.zeros((W, J, 3))
        for w, q in enumerate(Q):
            pin.forwardKinematics(model, data, q)
            for j in self._joints:
                M = data.oMi[j]
                R[w, j] = M.rotation
                t[w, j] = M.translation
        return R, t

    def candidates(
        self, R: FloatArray, t: FloatArray, a: IntArray, b: IntArray, margins: FloatArray
    ) -> NDArray[np.bool_]:
        """Which pairs ``(a[k], b[k])`` may be closer than ``margins[k]`` [m] at each of W configurations given by
        their joint placements (:meth:`joint_placements`); ``(W, P)``. The half-space, when in a pair, is ``b``."""
        p = self.parent
        centres = np.einsum("wnij,nj->wni", R[:, p], self.local_centre) + t[:, p]  # (W, n, 3)
        ca, cb = centres[:, a], centres[:, b]
        on_table = b == self.halfspace
        gap = np.linalg.norm(ca - cb, axis=2) - self.radius[a] - self.radius[b]
        gap = np.where(on_table, ca[:, :, 2] - self.radius[a] - self.height, gap)
        keep = gap <= margins + _SLACK
        w, k = np.nonzero(keep)
        if len(k) == 0:
            return keep
        ak, bk, mk = a[k], b[k], margins[k] + _SLACK
        RA = R[w, p[ak]] @ self.local_rotation[ak]
        hA = self.half[ak] + mk[:, None]
        low = ca[w, k, 2] - np.einsum("pk,pk->p", np.abs(RA[:, 2, :]), hA)  # the grown box's lowest point
        RB = R[w, p[bk]] @ self.local_rotation[bk]
        overlap = _boxes_overlap(RA, hA, ca[w, k], RB, self.half[bk], cb[w, k])
        keep[w, k] = np.where(on_table[k], low <= self.height, overlap)
        return keep


def _boxes_overlap(
    RA: FloatArray, hA: FloatArray, cA: FloatArray, RB: FloatArray, hB: FloatArray, cB: FloatArray
) -> NDArray[np.bool_]:
    """Separating-axis test of oriented boxes, pair by pair: rotations ``(P, 3, 3)`` (world from box), half-sizes
    ``(P, 3)`` [m], centres ``(P, 3)`` [m]. True where no axis separates them (they may overlap)."""
    R = np.einsum("pji,pjk->pik", RA, RB)  # B's axes in A's frame
    t = np.einsum("pji,pj->pi", RA, cB - cA)  # B's centre in A's frame
    AR = np.abs(R) + _PARALLEL
    sep = (np.abs(t) > hA + np.einsum("pij,pj->pi", AR, hB)).any(axis=1)
    tB = np.einsum("pij,pi->pj", R, t)
    sep |= (np.abs(tB) > np.einsum("pij,pi->pj", AR, hA) + hB).any(axis=1)
    # axes A_i x B_j, with (i1, i2) and (j1, j2) the other two indices in cyclic order
    ra = hA[:, _NEXT, None] * AR[:, _AFTER, :] + hA[:, _AFTER, None] * AR[:, _NEXT, :]
    rb = hB[:, None, _NEXT] * AR[:, :, _AFTER] + hB[:, None, _AFTER] * AR[:, :, _NEXT]
    lhs = np.abs(t[:, _AFTER, None] * R[:, _NEXT, :] - t[:, _NEXT, None] * R[:, _AFTER, :])
    sep |= (lhs > ra + rb).any(axis=(1, 2))
    return np.asarray(~sep)


def pair_arrays(pairs: Sequence[tuple[int, int]]) -> tuple[IntArray, IntArray]:
    """Index arrays (first, second) of geometry pairs; the half-space, when in a pair, must come second."""
    arr = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
    return arr[:, 0].copy(), arr[:, 1].copy()
