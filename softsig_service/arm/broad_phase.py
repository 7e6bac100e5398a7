"""Broad phase of the arm's collision checks: bounding spheres that rule pairs out before coal is asked.

Every geometry of a Pinocchio ``GeometryModel`` gets a sphere that contains it: the centre of its local AABB
(coal's ``aabb_center``, in the geometry's frame) carried into its parent joint's frame, and the AABB's
half-diagonal (``aabb_radius``) [m]. A half-space (the table, ``z <= h`` in the world frame) has no sphere: the
lower bound of a pair with it is the sphere's lowest point above the plane. At a configuration, a pair whose
lower bound exceeds its security margin cannot collide and is not handed to the narrow phase; the pairs that
remain are checked exactly as before, so the verdicts do not change.

Frames and units: world = UR5 ``base_link`` (z up); lengths in [m]; joint positions in [rad].
"""

from __future__ import annotations

from collections.abc import Sequence

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

_SLACK = 1e-9
"""[m] added to every margin so that rounding in the bounds never drops a pair that touches."""


class BoundingSpheres:
    """Spheres around the geometries of ``gm`` and, per pair list, the test that keeps the pairs that may collide.

    Args:
        gm: the geometry model (every object's ``placement`` is in its parent joint's frame).
        halfspace: index of the table's half-space geometry in ``gm`` (normal +z, offset ``height`` [m]).
        height: z [m] of the half-space's plane in the world.
    """

    def __init__(self, gm: pin.GeometryModel, halfspace: int, height: float) -> None:
        n = len(gm.geometryObjects)
        self.parent = np.zeros(n, dtype=np.intp)
        self.local_centre = np.zeros((n, 3))
        self.radius = np.zeros(n)
        for i, go in enumerate(gm.geometryObjects):
            self.parent[i] = int(go.parentJoint)
            if i == halfspace:
                continue
            geo = go.geometry
            geo.computeLocalAABB()
            self.local_centre[i] = go.placement.act(np.asarray(geo.aabb_center))
            self.radius[i] = float(geo.aabb_radius)
        self.halfspace = halfspace
        self.height = height
        self._joints = np.unique(self.parent)

    def move(self, index: int, placement: pin.SE3, geometry: coal.CollisionGeometry) -> None:
        """Update the sphere of geometry ``index`` after its ``placement`` (in its parent joint) changed."""
        self.local_centre[index] = placement.act(np.asarray(geometry.aabb_center))

    def centres(self, data: pin.Data) -> FloatArray:
        """World centres ``(n, 3)`` [m] of the spheres from the joint placements ``data.oMi`` (forward kinematics
        done by the caller)."""
        R = np.empty((len(data.oMi), 3, 3))
        t = np.zeros((len(data.oMi), 3))
        R[0] = np.eye(3)
        for j in self._joints:
            if j:
                M = data.oMi[int(j)]
                R[j] = M.rotation
                t[j] = M.translation
        p = self.parent
        return np.einsum("nij,nj->ni", R[p], self.local_centre) + t[p]

    def candidates(self, centres: FloatArray, a: IntArray, b: IntArray, margins: FloatArray) -> NDArray[np.bool_]:
        """Which pairs ``(a[k], b[k])`` may be closer than ``margins[k]`` [m] (lower bound of their distance)."""
        ca, cb = centres[a], centres[b]
        gap = np.linalg.norm(ca - cb, axis=1) - self.radius[a] - self.radius[b]
        on_table = b == self.halfspace
        gap = np.where(on_table, ca[:, 2] - self.radius[a] - self.height, gap)
        return np.asarray(gap <= margins + _SLACK)


def pair_arrays(pairs: Sequence[tuple[int, int]]) -> tuple[IntArray, IntArray]:
    """Index arrays (first, second) of geometry pairs; the half-space, when in a pair, must come second."""
    arr = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
    return arr[:, 0].copy(), arr[:, 1].copy()
