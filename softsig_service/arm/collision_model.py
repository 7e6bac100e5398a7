"""The geometry model of one collision world: the arm's links, the table, the hand's shapes and one object, with
every pair that is checked and the broad phase's bounding volumes (built once per object shape).

Frames and units: world = UR5 ``base_link`` (z up); hand shapes are posed in ``tool0``; lengths in [m].
Which pairs are checked, and why: :mod:`softsig_service.arm.collision`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from softsig_service.arm.arm_geometry import ArmGeometry
from softsig_service.arm.broad_phase import BroadPhase, pair_arrays
from softsig_service.arm.collision_report import (
    HAND_ATTACHED_LINKS,
    HAND_PREFIX,
    OBJECT_NAME,
    TABLE_EXCLUDED_LINKS,
    TABLE_NAME,
    Category,
)
from softsig_service.arm.pair_manager import PairManager, configure_requests
from softsig_service.arm.shapes import HandShape
from softsig_service.arm.ur5 import UR5

FloatArray = NDArray[np.float64]
SelectionKey = tuple[bool, bool, bool, bool, bool]
"""Flags that select pairs: (check_table, check_object, check_self, ignore_hand_object, ignore_hand_table)."""

CATEGORY_CODE: dict[str, int] = {"table": 0, "object": 1, "self": 2}
"""Index of each pair category in the margins array of the broad phase."""


@dataclass(frozen=True)
class PairInfo:
    """One checked pair: its index in the geometry model's pairs, category, names and kind."""

    index: int
    category: Category
    hand_object: bool
    names: tuple[str, str]
    hand: bool  # the first geometry is a hand shape


@dataclass
class WorldModel:
    """Pinocchio geometry model and data of a world, its pairs and broad phase, and the object it was built for
    (``obj``: coal geometry and pose ``T_world_shape``; ``key``: the shape's identity; ``object_id``: its index in
    ``gm``; ``broad_stale``: the object moved since the broad phase's volumes were set). ``selections`` caches
    the pairs chosen by a set of flags, ``managers`` their :class:`PairManager` (None: a geometry the manager
    cannot hold); ``applied_margins`` the margins last written into ``gd``'s requests."""

    gm: pin.GeometryModel
    gd: pin.GeometryData
    broad: BroadPhase
    pair_a: NDArray[np.intp]
    pair_b: NDArray[np.intp]
    pair_category: NDArray[np.intp]
    pairs: list[PairInfo]
    names: list[str]
    obj: tuple[coal.CollisionGeometry, FloatArray] | None
    key: tuple[object, ...] | None
    selections: dict[SelectionKey, tuple[list[PairInfo], NDArray[np.intp]]] = field(default_factory=dict)
    object_id: int | None = None
    broad_stale: bool = False
    managers: dict[SelectionKey, PairManager | None] = field(default_factory=dict)
    applied_margins: dict[str, float] = field(default_factory=dict)


def build_world_model(
    ur5: UR5,
    arm_geometry: ArmGeometry,
    hand_shapes: tuple[HandShape, ...],
    table_height: float,
    obj: tuple[coal.CollisionGeometry, FloatArray] | None,
    key: tuple[object, ...] | None,
) -> WorldModel:
    """The geometry model with the arm, the table (top at ``table_height`` [m]), the hand shapes, the object and
    all pairs."""
    arm = arm_geometry
    gm = pin.GeometryModel()
    names: list[str] = []
    for go, name in zip(arm.model.geometryObjects, arm.names, strict=True):
        gm.addGeometryObject(pin.GeometryObject(go))
        names.append(name)
    n_arm = len(names)
    table = coal.Halfspace(np.array([0.0, 0.0, 1.0]), table_height)
    table_id = gm.addGeometryObject(pin.GeometryObject(TABLE_NAME, 0, 0, pin.SE3.Identity(), table))
    names.append(TABLE_NAME)

    fid = ur5.flange_frame_id
    frame = ur5.model.frames[fid]
    joint_T_tool0 = np.array(frame.placement.homogeneous)
    hand_ids: list[int] = []
    for i, hs in enumerate(hand_shapes):
        T = joint_T_tool0 @ hs.pose_in_hand
        placement = pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())
        label = HAND_PREFIX + (hs.name or f"{hs.kind}{i}")
        go = pin.GeometryObject(label, int(frame.parentJoint), fid, placement, hs.geometry())
        hand_ids.append(gm.addGeometryObject(go))
        names.append(label)

    object_id: int | None = None
    if obj is not None:
        geo, pose = obj
        placement = pin.SE3(pose[:3, :3].copy(), pose[:3, 3].copy())
        object_id = gm.addGeometryObject(pin.GeometryObject(OBJECT_NAME, 0, 0, placement, geo))
        names.append(OBJECT_NAME)

    specs: list[tuple[int, int, Category, bool]] = [(a, b, "self", False) for a, b in arm.self_pairs]
    hand_set = set(hand_ids)
    for a in range(n_arm):
        if names[a] not in TABLE_EXCLUDED_LINKS:
            specs.append((a, table_id, "table", False))
        if object_id is not None:
            specs.append((a, object_id, "object", False))
    for h in hand_ids:
        specs.append((h, table_id, "table", False))
        if object_id is not None:
            specs.append((h, object_id, "object", True))
        for a in range(n_arm):
            if names[a] not in HAND_ATTACHED_LINKS:
                specs.append((a, h, "self", False))

    pairs: list[PairInfo] = []
    for a, b, cat, ho in specs:
        gm.addCollisionPair(pin.CollisionPair(a, b))
        k = len(pairs)
        pairs.append(PairInfo(k, cat, ho, (names[a], names[b]), a in hand_set))
    gd = pin.GeometryData(gm)
    configure_requests(gd)
    pair_a, pair_b = pair_arrays([(a, b) for a, b, _, _ in specs])
    return WorldModel(
        gm=gm,
        gd=gd,
        broad=BroadPhase(gm, table_id, table_height),
        pair_a=pair_a,
        pair_b=pair_b,
        pair_category=np.array([CATEGORY_CODE[p.category] for p in pairs], dtype=np.intp),
        pairs=pairs,
        names=names,
        obj=obj,
        key=key,
        object_id=object_id,
    )
