"""How far the open hand can travel along its approach before it touches the table or the object (coal).

The hand's collision primitives (in the hand frame) are posed by a flange pose ``T_world_hand`` and measured
against the table (the half-space below z = table_height, as a large thin box) and the object. A straight
approach is advanced conservatively: moving every point of the hand by ``s`` along a unit direction changes
any distance by at most ``s``, so a step of (distance - margin) never passes through anything.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import coal
import numpy as np
from numpy.typing import NDArray

from softsig_service.arm.shapes import HandShape, local_aabb, object_geometry
from softsig_service.objects import TableObject

TABLE_HALF_THICKNESS = 0.05
"""[m] the table is a 6 x 6 x 0.1 m box whose top face is the table plane."""


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


_TABLE_BOUND_SLACK = 1e-5
"""[m] the exact height bound of a shape above the table is lowered by this before culling, so that coal's own
rounding (its GJK tolerance is 1e-6) never drops the nearest shape."""


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
        across = np.sqrt(np.maximum(0.0, 1.0 - up[:, 2] ** 2))
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

    ``lowest`` (n,) [m]: world z of each shape's lowest point; ``centres`` (n, 3) [m]: bounding-sphere centres;
    ``centres_in_object`` (n, 3): the same in the object's primitive axes; ``rotations`` (n, 3, 3) and
    ``origins`` (n, 3) [m]: each shape's pose in the world.
    """

    lowest: NDArray[np.float64]
    centres: NDArray[np.float64]
    centres_in_object: NDArray[np.float64]
    rotations: NDArray[np.float64]
    origins: NDArray[np.float64]


class HandClearance:
    """Distances [m] from the open hand's primitives to the table and one object (one per plan and thread).

    ``hand`` is the hand's :class:`HandGeometry` (built from ``hand_shapes`` when not given); the object's coal
    geometry comes from :func:`~softsig_service.arm.shapes.object_geometry` (a mesh's is built once per content).
    """

    def __init__(
        self,
        hand_shapes: Sequence[HandShape],
        obj: TableObject | None,
        table_height: float,
        hand: HandGeometry | None = None,
    ) -> None:
        self._hand = hand if hand is not None else HandGeometry(hand_shapes)
        self._shapes = self._hand.shapes
        self._centres = self._hand.centres
        self._radii = self._hand.radii
        self._table_height = table_height
        self._table = coal.Box(6.0, 6.0, 2 * TABLE_HALF_THICKNESS)
        T_table = np.eye(4)
        T_table[2, 3] = table_height - TABLE_HALF_THICKNESS
        self._table_tf = _tf(T_table)
        self._object = None
        self._object_centre = np.zeros(3)
        self._object_radius = 0.0
        self._object_R = np.eye(3)
        self._object_half = np.zeros(3)
        if obj is not None:
            geom = local_aabb(object_geometry(obj.primitive()))
            T_obj = obj.primitive_pose
            self._object = (geom, _tf(T_obj))
            lo, hi = np.asarray(geom.aabb_local.min_), np.asarray(geom.aabb_local.max_)
            self._object_R = T_obj[:3, :3]
            self._object_centre = T_obj[:3, 3] + T_obj[:3, :3] @ (0.5 * (lo + hi))
            self._object_half = 0.5 * (hi - lo)
            self._object_radius = float(geom.aabb_radius)
        self._req = coal.DistanceRequest()
        self._last: tuple[bytes, tuple[float, float]] | None = None  # the last pose asked and its answer
        self._orientations: dict[bytes, _Posed] = {}

    def distances(self, T_world_hand: NDArray[np.float64]) -> tuple[float, float]:
        """(to the table, to the object) [m]; negative inside; +inf for a missing object.

        Exact coal distances, queried only for shapes whose lower bound could beat the best found so far: for the
        table the exact height of the shape's lowest point above the plane (the table lies inside the half-space
        below it), for the object the gap between the shape's bounding sphere and the object's bounding box (signed
        distance in the object's primitive frame) or bounding sphere, whichever is larger. What depends on the
        hand's orientation alone is computed once per orientation (:class:`_Posed`): a descent only translates.
        """
        key = T_world_hand.tobytes()
        if self._last is not None and self._last[0] == key:
            return self._last[1]  # the descent asks again at the pose where it stopped
        posed = self._posed(T_world_hand[:3, :3])
        t = T_world_hand[:3, 3]
        bound_table = posed.lowest + (t[2] - self._table_height - _TABLE_BOUND_SLACK)
        poses: dict[int, coal.Transform3s] = {}  # shape poses, built once per call for both queries
        d_table = self._nearest(posed, t, poses, bound_table, self._table, self._table_tf)
        d_obj = float("inf")
        if self._object is not None:
            shift = t - self._object_centre
            offset = posed.centres + shift
            excess = np.abs(posed.centres_in_object + shift @ self._object_R) - self._object_half
            box_sdf = np.linalg.norm(np.maximum(excess, 0.0), axis=1) + np.minimum(excess.max(axis=1), 0.0)
            gap = np.maximum(box_sdf, np.linalg.norm(offset, axis=1) - self._object_radius)
            gap -= self._radii
            d_obj = self._nearest(posed, t, poses, gap, *self._object)
        self._last = (key, (d_table, d_obj))
        return d_table, d_obj

    def _posed(self, R: NDArray[np.float64]) -> _Posed:
        """The orientation-only terms of the hand at the rotation ``R`` (world from flange), cached by value."""
        key = R.tobytes()
        posed = self._orientations.get(key)
        if posed is None:
            R = np.array(R, dtype=np.float64)
            lowest = self._hand.lowest_points(_pose(R, np.zeros(3)))
            centres = self._centres @ R.T
            rotations = np.matmul(R, self._hand.rotations)  # (n, 3, 3), each contiguous
            origins = self._hand.origins @ R.T
            posed = _Posed(lowest, centres, centres @ self._object_R, rotations, origins)
            if len(self._orientations) >= _ORIENTATIONS_KEPT:
                self._orientations.clear()
            self._orientations[key] = posed
        return posed

    def _nearest(
        self,
        posed: _Posed,
        t: NDArray[np.float64],
        poses: dict[int, coal.Transform3s],
        lower_bounds: NDArray[np.float64],
        other: coal.CollisionGeometry,
        other_tf: coal.Transform3s,
    ) -> float:
        best = float("inf")
        for k in np.argsort(lower_bounds).tolist():
            if lower_bounds[k] >= best:
                break
            tf = poses.get(k)
            if tf is None:
                tf = poses[k] = coal.Transform3s(posed.rotations[k], posed.origins[k] + t)
            result = coal.distance(self._shapes[k][0], tf, other, other_tf, self._req, coal.DistanceResult())
            best = min(best, result)
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
        d = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
        travel = 0.0
        T = np.array(T_start, dtype=float)
        for _ in range(max_steps):
            d_table, d_obj = self.distances(T)
            gap = min(d_table, d_obj) - margin
            if gap <= tolerance or travel >= max_travel:
                break
            step = min(gap, max_travel - travel)
            travel += step
            T[:3, 3] = T_start[:3, 3] + travel * d
        d_table, d_obj = self.distances(T)
        if travel >= max_travel and min(d_table, d_obj) - margin > tolerance:
            limited = "travel"
        else:
            limited = "table" if d_table <= d_obj else "object"
        return Descent(T_world_hand=T, travel=travel, limited_by=limited, distance=min(d_table, d_obj))
