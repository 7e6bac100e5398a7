"""How far the open hand can travel along its approach before it touches the table or the object (coal).

The hand's collision primitives (in the hand frame) are posed by a flange pose ``T_world_hand`` and measured
against the table (the plane z = table_height, with the half-space below it) and the object. The distance of a
box, sphere, capsule or cylinder to the table is the height of its lowest point above the plane, exactly and in
closed form (negative: that deep below it); the object's distances are coal's. A straight
approach is advanced conservatively: moving every point of the hand by ``s`` along a unit direction changes
any distance by at most ``s``, so a step of (distance - margin) never passes through anything.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import coal
import numpy as np
from numpy.typing import NDArray

from softsig_service.arm.shapes import HandShape, local_aabb, object_geometry
from softsig_service.objects import TableObject


def _tf(T: NDArray[np.float64]) -> coal.Transform3s:
    return coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


@dataclass(frozen=True)
class Descent:
    """Result of :meth:`HandClearance.descend`: the pose where the approach stops and what stops it."""

    T_world_hand: NDArray[np.float64]
    travel: float
    """[m] travelled from the start pose."""
    limited_by: str
    """``"table"``, ``"object"`` or ``"travel"`` (the full travel was free)."""
    distance: float
    """[m] clearance to the nearest of table and object at the stop."""


class HandGeometry:
    """The hand's primitives as coal geometries with what culling needs, built once per hand.

    Per shape (hand frame = ``tool0``): the coal geometry and its pose ``T_hand_shape``, the centre [m] and radius
    [m] of its bounding sphere, and the terms of its exact lowest point along any direction: ``half_box`` ``(3,)``
    [m] (box half-sizes; (0, 0, half-length) for a cylinder or capsule), ``disc`` [m] (a cylinder's radius) and
    ``ball`` [m] (a sphere's or a capsule's radius). Read-only after construction: share it between threads.
    """

    def __init__(self, hand_shapes: Sequence[HandShape]) -> None:
        self.shapes = [(s.geometry(), np.asarray(s.pose_in_hand)) for s in hand_shapes]
        for geom, _ in self.shapes:
            local_aabb(geom)
        n = len(self.shapes)
        self.rotations = np.array([T[:3, :3] for _, T in self.shapes]).reshape(n, 3, 3)
        self.origins = np.array([T[:3, 3] for _, T in self.shapes]).reshape(n, 3)
        self.centres = np.array([T[:3, 3] + T[:3, :3] @ g.aabb_center for g, T in self.shapes]).reshape(n, 3)
        self.radii = np.array([g.aabb_radius for g, _ in self.shapes])
        self.extent = float(np.max(np.linalg.norm(self.centres, axis=1) + self.radii)) if n else 0.0
        """[m] how far the hand reaches from the flange's origin (bounding spheres)."""
        self.half_box = np.zeros((n, 3))
        self.disc = np.zeros(n)
        self.ball = np.zeros(n)
        for i, s in enumerate(hand_shapes):
            if s.kind == "box":
                self.half_box[i] = s.size
            elif s.kind == "sphere":
                self.ball[i] = s.size[0]
            else:  # capsule or cylinder: (radius, half-length), axis along the shape's z
                self.half_box[i, 2] = s.size[1]
                if s.kind == "cylinder":
                    self.disc[i] = s.size[0]
                else:
                    self.ball[i] = s.size[0]

    def lowest_points(self, T_world_hand: NDArray[np.float64]) -> NDArray[np.float64]:
        """World z [m] of each shape's lowest point at the flange pose ``T_world_hand``."""
        up = T_world_hand[2, :3] @ self.rotations  # (n, 3): world z in each shape's frame
        z = self.origins @ T_world_hand[2, :3] + T_world_hand[2, 3]
        across = np.hypot(up[:, 0], up[:, 1])  # sin of the axis's tilt; sqrt(1 - cos^2) cancels near vertical
        return np.asarray(z - (np.abs(up) * self.half_box).sum(axis=1) - self.disc * across - self.ball)


_ORIENTATIONS_KEPT = 8
"""Orientations whose terms a :class:`HandClearance` keeps (a plan descends along one or two)."""


def _pose(R: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


@dataclass(frozen=True, eq=False)
class _Posed:
    """The hand's terms at one orientation R, all at zero translation (add the flange position t).

    ``lows`` (n,) [m]: world z of each shape's lowest point, ``lowest`` [m] the smallest of them;
    ``centres_in_object`` (n, 3) [m]: the shapes' bounding-sphere centres in the object's primitive axes;
    ``rotations`` (n, 3, 3) and ``origins`` (n, 3) [m]: each shape's pose in the world.
    """

    lows: NDArray[np.float64]
    lowest: float
    centres_in_object: NDArray[np.float64]
    rotations: NDArray[np.float64]
    origins: NDArray[np.float64]


class HandClearance:
    """Distances [m] from the open hand's primitives to the table and one object (one per plan and thread).

    ``hand`` is the hand's :class:`HandGeometry` (built from ``hand_shapes`` when not given); the object's coal
    geometry is ``placed`` (the geometry of ``obj.primitive()`` and its pose ``T_world_primitive``, e.g. a
    collision world's that holds the object already) or else comes from
    :func:`~softsig_service.arm.shapes.object_geometry` (a mesh's is built once per content).
    """

    def __init__(
        self,
        hand_shapes: Sequence[HandShape],
        obj: TableObject | None,
        table_height: float,
        hand: HandGeometry | None = None,
        placed: tuple[coal.CollisionGeometry, NDArray[np.float64]] | None = None,
    ) -> None:
        self._hand = hand if hand is not None else HandGeometry(hand_shapes)
        self._shapes = self._hand.shapes
        self._centres = self._hand.centres
        self._radii = self._hand.radii
        self._table_height = table_height
        self._object = None
        self._object_centre = np.zeros(3)
        self._object_R = np.eye(3)
        self._object_half = np.zeros(3)
        self._object_top = 0.0
        """[m] world z of the highest point of the object's bounding box (no object: unused)."""
        if obj is not None:
            geom, T_obj = placed if placed is not None else (object_geometry(obj.primitive()), obj.primitive_pose)
            local_aabb(geom)
            self._object = (geom, _tf(T_obj))
            lo, hi = np.asarray(geom.aabb_local.min_), np.asarray(geom.aabb_local.max_)
            self._object_R = T_obj[:3, :3]
            self._object_centre = T_obj[:3, 3] + T_obj[:3, :3] @ (0.5 * (lo + hi))
            self._object_half = 0.5 * (hi - lo)
            self._object_top = float(self._object_centre[2] + np.abs(self._object_R[2]) @ self._object_half)
        self._req = coal.DistanceRequest()
        self._tf = coal.Transform3s()
        self._res = coal.DistanceResult()
        self._last: tuple[bytes, float, float, bool] | None = None  # the last pose asked and its answer
        self._orientations: dict[bytes, _Posed] = {}

    @property
    def extent(self) -> float:
        """[m] how far the hand reaches from the flange's origin (:attr:`HandGeometry.extent`)."""
        return self._hand.extent

    def distances(self, T_world_hand: NDArray[np.float64]) -> tuple[float, float]:
        """(to the table, to the object) [m]; negative inside; +inf for a missing object.

        The table's is exact (the lowest point of the hand's primitives); the object's are coal distances, queried
        only for shapes whose lower bound could beat the best found so far. A shape's lower bound is the larger
        of two: the gap between its bounding sphere and the object's bounding box (signed distance in the
        object's primitive frame; the box lies inside the object's bounding sphere, so this is the tighter of the
        two), and the height of its lowest point above the box's highest (two sets are at least as far apart as
        along any direction; overlapping by h along it, one translation of h separates them, so no deeper than
        h either). What depends on the hand's orientation alone is computed once per orientation
        (:class:`_Posed`): a descent only translates.
        """
        d_table, d_obj, _ = self._measure(T_world_hand, nearest_only=False)
        return d_table, d_obj

    def nearest(self, T_world_hand: NDArray[np.float64]) -> tuple[float, str]:
        """The hand's clearance [m] to the nearer of table and object at ``T_world_hand`` (negative inside), and
        which it is (``"table"`` on a tie): ``min(distances(T_world_hand))``, with coal asked only about shapes
        that could come nearer the object than the table is."""
        d_table, d_obj, _ = self._measure(T_world_hand, nearest_only=True)
        return (d_obj, "object") if d_obj < d_table else (d_table, "table")

    def _measure(self, T_world_hand: NDArray[np.float64], nearest_only: bool) -> tuple[float, float, bool]:
        """(d_table, d_obj, whether d_obj is exact) [m]. With ``nearest_only`` the object's distance is exact only
        where it is below the table's; elsewhere it is some value not below the table's."""
        key = T_world_hand.tobytes()
        if self._last is not None and self._last[0] == key and (self._last[3] or nearest_only):
            return self._last[1:]  # the descent asks again at the pose where it stopped
        posed = self._posed(T_world_hand[:3, :3])
        t = T_world_hand[:3, 3]
        d_table = posed.lowest + float(t[2]) - self._table_height
        d_obj = float("inf")
        if self._object is not None:
            shift = t - self._object_centre
            excess = np.abs(posed.centres_in_object + shift @ self._object_R) - self._object_half
            outside = np.maximum(excess, 0.0)  # (norms written out: np.linalg.norm's checks cost more here)
            gap = np.sqrt((outside * outside).sum(axis=1)) + np.minimum(excess.max(axis=1), 0.0)
            bounds = np.maximum(gap - self._radii, posed.lows + (float(t[2]) - self._object_top))
            d_obj = self._nearest(posed, t, bounds, d_table if nearest_only else float("inf"), *self._object)
        exact = not nearest_only or d_obj < d_table
        self._last = (key, d_table, d_obj, exact)
        return d_table, d_obj, exact

    def _posed(self, R: NDArray[np.float64]) -> _Posed:
        """The orientation-only terms of the hand at the rotation ``R`` (world from flange), cached by value."""
        key = R.tobytes()
        posed = self._orientations.get(key)
        if posed is None:
            R = np.array(R, dtype=np.float64)
            lows = self._hand.lowest_points(_pose(R, np.zeros(3)))
            centres_in_object = self._centres @ R.T @ self._object_R
            rotations = np.matmul(R, self._hand.rotations)  # (n, 3, 3), each contiguous
            origins = self._hand.origins @ R.T
            posed = _Posed(lows, float(lows.min()), centres_in_object, rotations, origins)
            if len(self._orientations) >= _ORIENTATIONS_KEPT:
                self._orientations.clear()
            self._orientations[key] = posed
        return posed

    def _nearest(
        self,
        posed: _Posed,
        t: NDArray[np.float64],
        lower_bounds: NDArray[np.float64],
        below: float,
        other: coal.CollisionGeometry,
        other_tf: coal.Transform3s,
    ) -> float:
        """The smallest distance [m] of the hand's shapes to ``other`` if it is below ``below`` [m]; else some value
        not below ``below`` (shapes whose ``lower_bounds`` [m] reach ``below`` are not asked)."""
        best = below
        tf, res = self._tf, self._res  # reused: set in full before each query
        for k in np.argsort(lower_bounds).tolist():
            if lower_bounds[k] >= best:
                break
            tf.setRotation(posed.rotations[k])
            tf.setTranslation(posed.origins[k] + t)
            res.clear()
            best = min(best, coal.distance(self._shapes[k][0], tf, other, other_tf, self._req, res))
        return best

    def descend(
        self,
        T_start: NDArray[np.float64],
        direction: NDArray[np.float64],
        max_travel: float,
        margin: float,
        *,
        tolerance: float = 5e-4,
        max_steps: int = 200,
    ) -> Descent:
        """Advance ``T_start`` along the unit ``direction`` (world) until ``margin`` [m] from table or object."""
        d = np.asarray(direction, dtype=float)
        d = d / math.sqrt(float(d @ d))
        travel = 0.0
        T = np.array(T_start, dtype=float)
        for _ in range(max_steps):
            gap = self.nearest(T)[0] - margin
            if gap <= tolerance or travel >= max_travel:
                break
            step = min(gap, max_travel - travel)
            travel += step
            T[:3, 3] = T_start[:3, 3] + travel * d
        distance, nearer = self.nearest(T)
        limited = "travel" if travel >= max_travel and distance - margin > tolerance else nearer
        return Descent(T_world_hand=T, travel=travel, limited_by=limited, distance=distance)
