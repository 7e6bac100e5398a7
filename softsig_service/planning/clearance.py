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

from softsig_service.arm.shapes import HandShape, object_geometry
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


class HandClearance:
    """Distances [m] from the open hand's primitives to the table and one object."""

    def __init__(self, hand_shapes: Sequence[HandShape], obj: TableObject | None, table_height: float) -> None:
        self._shapes = [(s.geometry(), np.asarray(s.pose_in_hand)) for s in hand_shapes]
        for geom, _ in self._shapes:
            geom.computeLocalAABB()
        # bounding spheres (centre in the hand frame, radius) for culling exact distance queries
        self._centres = np.array([T[:3, 3] + T[:3, :3] @ g.aabb_center for g, T in self._shapes]).reshape(-1, 3)
        self._radii = np.array([g.aabb_radius for g, _ in self._shapes])
        self._table_height = table_height
        self._table = coal.Box(6.0, 6.0, 2 * TABLE_HALF_THICKNESS)
        T_table = np.eye(4)
        T_table[2, 3] = table_height - TABLE_HALF_THICKNESS
        self._table_tf = _tf(T_table)
        self._object = None
        self._object_centre = np.zeros(3)
        self._object_radius = 0.0
        if obj is not None:
            geom = object_geometry(obj.primitive())
            geom.computeLocalAABB()
            T_obj = obj.primitive_pose
            self._object = (geom, _tf(T_obj))
            self._object_centre = T_obj[:3, 3] + T_obj[:3, :3] @ geom.aabb_center
            self._object_radius = float(geom.aabb_radius)
        self._req = coal.DistanceRequest()

    def distances(self, T_world_hand: NDArray[np.float64]) -> tuple[float, float]:
        """(to the table, to the object) [m]; negative inside; +inf for a missing object.

        Exact coal distances, queried only for shapes whose bounding sphere could beat the best found so far.
        """
        centres = self._centres @ T_world_hand[:3, :3].T + T_world_hand[:3, 3]
        bound_table = centres[:, 2] - self._table_height - self._radii
        poses: dict[int, coal.Transform3s] = {}  # shape poses, built once per call for both queries
        d_table = self._nearest(T_world_hand, poses, bound_table, self._table, self._table_tf)
        d_obj = float("inf")
        if self._object is not None:
            gap = np.linalg.norm(centres - self._object_centre, axis=1) - self._radii - self._object_radius
            d_obj = self._nearest(T_world_hand, poses, gap, *self._object)
        return d_table, d_obj

    def _nearest(
        self,
        T_world_hand: NDArray[np.float64],
        poses: dict[int, coal.Transform3s],
        lower_bounds: NDArray[np.float64],
        other: coal.CollisionGeometry,
        other_tf: coal.Transform3s,
    ) -> float:
        best = float("inf")
        for k in np.argsort(lower_bounds):
            if lower_bounds[k] >= best:
                break
            geom, T_shape = self._shapes[k]
            tf = poses.get(int(k))
            if tf is None:
                tf = poses[int(k)] = _tf(T_world_hand @ T_shape)
            best = min(best, coal.distance(geom, tf, other, other_tf, self._req, coal.DistanceResult()))
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
