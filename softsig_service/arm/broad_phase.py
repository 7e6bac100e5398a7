"""Broad phase of the arm's collision checks: bounding volumes that rule pairs out before coal is asked.

Every geometry of a Pinocchio ``GeometryModel`` gets two bounding volumes built from coal's local AABB (in the
geometry's own frame): the oriented box of that AABB (OBB, carried by the geometry's placement and its parent
joint) and the sphere around it (the AABB's centre and half-diagonal ``aabb_radius``) [m]. A half-space (the
table, ``z <= h`` in the world frame) has neither: a pair with it is bounded by the OBB's lowest point.

At a configuration, a pair with the half-space is kept when the first geometry's OBB, grown by the pair's
security margin on every side (a superset of all points within the margin), reaches the plane; any other pair
when the two spheres are within the margin. A pair ruled out cannot collide; the others are handed to coal
exactly as before, so the verdicts do not change.

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
        H = np.empty((len(Q), model.njoints, 4, 4))
        for w, q in enumerate(Q):
            pin.forwardKinematics(model, data, q)
            H[w] = [M.homogeneous for M in data.oMi]
        return H[:, :, :3, :3], H[:, :, :3, 3]

    def candidates(
        self, R: FloatArray, t: FloatArray, a: IntArray, b: IntArray, margins: FloatArray
    ) -> NDArray[np.bool_]:
        """Which pairs ``(a[k], b[k])`` may be closer than ``margins[k]`` [m] at each of W configurations given by
        their joint placements (:meth:`joint_placements`); ``(W, P)``. The half-space, when in a pair, is ``b``.

        A pair with the half-space is kept when the lowest point of the first geometry's box, grown by the margin,
        is not above the plane; any other pair when the bounding spheres are within the margin. Nothing finer
        is worth it here: coal answers a pair of convex shapes that the spheres keep in well under a microsecond,
        less than a vectorised separating-axis test costs per pair in NumPy."""
        p = self.parent
        Rp = R[:, p]  # (W, n, 3, 3): each geometry's parent joint
        centres = np.einsum("wnij,nj->wni", Rp, self.local_centre) + t[:, p]  # (W, n, 3)
        up = np.abs(np.einsum("wnj,njk->wnk", Rp[:, :, 2, :], self.local_rotation))  # |world z| in box axes
        low = centres[:, :, 2] - np.einsum("wnk,nk->wn", up, self.half)  # (W, n): each box's lowest point
        grown = margins + _SLACK
        diff = centres[:, a] - centres[:, b]
        limit = self.radius[a] + self.radius[b] + grown
        near = np.einsum("wpk,wpk->wp", diff, diff) <= limit * limit
        # a box grown by m on every side is lower by m * sum(|world z| in box axes)
        reaches_table = low[:, a] - grown * up.sum(axis=2)[:, a] <= self.height
        return np.where(b == self.halfspace, reaches_table, near)


def pair_arrays(pairs: Sequence[tuple[int, int]]) -> tuple[IntArray, IntArray]:
    """Index arrays (first, second) of geometry pairs; the half-space, when in a pair, must come second."""
    arr = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
    return arr[:, 0].copy(), arr[:, 1].copy()
