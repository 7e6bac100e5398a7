"""Collision world of the UR5, the mounted hand, the table and one object (coal, through Pinocchio).

Frames and units: the world frame is the UR5 ``base_link`` (z up); lengths in [m]; poses are 4x4 homogeneous
transforms. The hand frame *is* the ``tool0`` frame (docs/design.md §3): hand shapes are rigidly attached to it.

What is in the world:

* **Arm links**: the collision STL meshes of ``ur5_robot.urdf`` (loaded with
  ``pinocchio.buildGeomFromUrdf``), each replaced by its **convex hull** (qhull, built once per process). The
  hulls contain the meshes, so checks are conservative; on the UR5 the distances differ from the meshes' by
  about 1 mm. Measured on the bare arm with the table: collisions ~6 µs with hulls vs ~0.6 ms with the
  triangle meshes (slow against a half-space), distances ~9 µs vs ~6 ms.
* **Table**: the half-space ``z <= table_height`` (``coal.Halfspace``): its top is the plane
  ``z = table_height``.
* **Object**: one shape (box, cylinder, sphere, ellipsoid or the convex hull of a vertex set) at a 4x4 pose.
* **Hand**: a list of :class:`HandShape` primitives posed in the hand (= ``tool0``) frame.

Which pairs are checked, and under which reason (``CollisionReport.reasons``):

* ``"collision:self"``: the arm's link pairs that the SRDF (``srdf/ur5.srdf``) does not disable (27 -> 17
  pairs), and every hand shape against ``base_link``, ``shoulder_link``, ``upper_arm_link``, ``forearm_link``,
  ``wrist_1_link`` and ``wrist_2_link``. Hand shapes are not checked against ``wrist_3_link`` and ``ee_link``
  (rigidly attached: the hand is bolted to that flange) nor against each other.
* ``"collision:table"``: every arm link except ``base_link`` and ``shoulder_link`` (the base stands on the
  table: its mesh reaches 3 mm below ``base_link``'s origin), and every hand shape, against the table.
* ``"collision:object"``: every arm link and every hand shape against the object; the hand–object pairs can be
  left out with ``ignore_hand_object=True`` (at a grasp pose the hand is meant to touch the object). The
  object is never checked against the table (it rests on it).

A pair counts as colliding when its shapes are closer than the security margin [m] (0: touching or
penetrating): ``margin`` for object pairs, ``table_margin`` for table pairs and ``self_margin`` for self
pairs (the wrist links sit a few cm from each other in ordinary poses). Keep ``table_margin``
below ~0.02 m with the table at the base's height: the shoulder end of ``upper_arm_link`` stays about 0.03 m
above such a table in every configuration (shoulder axis 0.089 m up, link radius ~0.06 m).

A :class:`CollisionWorld` holds mutable Pinocchio/coal data: use one per thread.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from typing import TypedDict

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray
from typing_extensions import Unpack

from softsig_service.arm.arm_geometry import arm_geometry
from softsig_service.arm.collision_model import PairInfo, SelectionKey, WorldModel, build_world_model
from softsig_service.arm.collision_report import (
    CATEGORY_ORDER,
    REASON_OF,
    CollisionReport,
    check_finite,
    check_margin,
    make_report,
    min_optional,
)
from softsig_service.arm.pair_manager import PairManager
from softsig_service.arm.shapes import (
    HandShape,
    ShapeSpec,
    object_geometry,
)
from softsig_service.arm.ur5 import UR5
from softsig_service.errors import InvalidInput
from softsig_service.geometry.transforms import check_transform

FloatArray = NDArray[np.float64]


_BUILT_WORLDS = 8
"""How many object shapes a world keeps built (least recently used dropped), so that objects can alternate."""


class CheckOptions(TypedDict, total=False):
    """Options of a collision check (:meth:`CollisionWorld.check`); every one may be left out.

    ``margin``, ``table_margin``, ``self_margin``: security margins [m] of the object, table and self pairs
    (default: the world's); ``ignore_hand_object``, ``ignore_hand_table``: leave out the hand-shape/object or
    hand-shape/table pairs (default False; e.g. where the caller has shown those shapes clear already);
    ``check_table``, ``check_object``, ``check_self``: which pair groups to check (default all);
    ``distances``: also compute the smallest distances [m] to the table and the object (default True).
    """

    margin: float | None
    table_margin: float | None
    self_margin: float | None
    ignore_hand_object: bool
    ignore_hand_table: bool
    check_table: bool
    check_object: bool
    check_self: bool
    distances: bool


class PathOptions(CheckOptions, total=False):
    """:class:`CheckOptions` of a sequence of configurations, and ``stop_at_first`` (default True): stop at the
    first colliding configuration."""

    stop_at_first: bool


class CollisionWorld:
    """Arm + hand + table + object collision checks at joint configurations of the UR5.

    Args:
        ur5: the arm model (:func:`softsig_service.arm.ur5.load_ur5`).
        hand_shapes: primitives attached to the hand (= ``tool0``) frame; may be empty (bare flange).
        table_height: z [m] of the table top in the world frame.
        margin: default security margin [m] for object pairs: closer than this counts as colliding.
        table_margin: default security margin [m] for the table pairs (see the module notes).
        self_margin: default security margin [m] for the self pairs (arm/arm and hand/arm).
    """

    def __init__(
        self,
        ur5: UR5,
        hand_shapes: Sequence[HandShape] = (),
        table_height: float = 0.0,
        *,
        margin: float = 0.0,
        table_margin: float = 0.0,
        self_margin: float = 0.0,
    ) -> None:
        self.ur5 = ur5
        self.hand_shapes = tuple(hand_shapes)
        for i, hs in enumerate(self.hand_shapes):
            if not isinstance(hs, HandShape):
                raise InvalidInput("expected a HandShape", field=f"hand_shapes[{i}]", value=repr(hs))
        self.table_height = check_finite(table_height, "table_height")
        self.margin = check_margin(margin)
        self.table_margin = check_margin(table_margin, "table_margin")
        self.self_margin = check_margin(self_margin, "self_margin")
        self._arm = arm_geometry(ur5.urdf_path, ur5.srdf_path, ur5.package_dir)
        self._model = ur5.model
        self._data = ur5.model.createData()
        self._w = self._build(None, None)
        self._built: OrderedDict[tuple[object, ...], WorldModel] = OrderedDict()

    def _build(
        self, obj: tuple[coal.CollisionGeometry, FloatArray] | None, key: tuple[object, ...] | None
    ) -> WorldModel:
        """The geometry model of this world with the object ``obj`` (None: no object)."""
        return build_world_model(self.ur5, self._arm, self.hand_shapes, self.table_height, obj, key)

    # -- construction ------------------------------------------------------------------------------------

    def set_object(self, shape: ShapeSpec, pose: ArrayLike) -> None:
        """Put one object in the world (replacing any previous one).

        Args:
            shape: the object's shape in its own frame (:class:`ObjectShape`, or
                ``softsig_service.objects`` primitives), MuJoCo size conventions.
            pose: 4x4 pose ``T_world_shape`` of the shape frame [m].
        """
        self.set_object_unchecked(shape, check_transform(pose, field="object.pose").copy())

    def set_object_unchecked(self, shape: ShapeSpec, T: FloatArray) -> None:
        """:meth:`set_object` for callers that pass a checked rigid 4x4 float transform ``T`` [m] (not copied)."""
        content = getattr(shape, "content_key", None)
        if content is None and shape.vertices is not None:
            content = np.asarray(shape.vertices).tobytes()
        key = (shape.kind, tuple(shape.size), content)
        w = self._w
        if w.obj is None or key != w.key:
            if w.key is not None:  # keep the current world for when its object comes back
                self._built[w.key] = w
            cached = self._built.pop(key, None)
            w = self._w = cached if cached is not None else self._build((object_geometry(shape), T), key)
            self._built[key] = w
            while len(self._built) > _BUILT_WORLDS:
                self._built.popitem(last=False)
        assert w.obj is not None
        # same shape, new pose: move the existing geometry instead of rebuilding the world
        geo = w.obj[0]
        w.obj = (geo, T)
        assert w.object_id is not None
        w.gm.geometryObjects[w.object_id].placement = pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())
        w.broad_stale = True  # the NumPy broad phase follows when next asked (_may_collide)

    def clear_object(self) -> None:
        """Remove the object from the world."""
        self._w = self._build(None, None)

    @property
    def placed_object(self) -> tuple[coal.CollisionGeometry, FloatArray] | None:
        """The object's coal geometry and pose ``T_world_shape`` [m] (read-only), or None without an object."""
        return self._w.obj

    @property
    def has_object(self) -> bool:
        """Whether an object is in the world."""
        return self._w.obj is not None

    @property
    def pair_names(self) -> list[tuple[str, str, str]]:
        """Every pair the world can check, as (name, name, category)."""
        return [(p.names[0], p.names[1], p.category) for p in self._w.pairs]

    # -- checks ----------------------------------------------------------------------------------------------

    def _margins(self, margin: float | None, table_margin: float | None, self_margin: float | None) -> dict[str, float]:
        return {
            "object": self.margin if margin is None else check_margin(margin),
            "table": self.table_margin if table_margin is None else check_margin(table_margin, "table_margin"),
            "self": self.self_margin if self_margin is None else check_margin(self_margin, "self_margin"),
        }

    def _apply_margins(self, margins: dict[str, float]) -> None:
        if margins == self._w.applied_margins:
            return
        reqs = self._w.gd.collisionRequests
        for p in self._w.pairs:
            reqs[p.index].security_margin = margins[p.category]
        self._w.applied_margins = margins

    def _selected(self, key: SelectionKey) -> tuple[list[PairInfo], NDArray[np.intp]]:
        """The pairs the flags ``key`` = (check_table, check_object, check_self, ignore_hand_object,
        ignore_hand_table) select, and their indices (built once per combination of flags)."""
        hit = self._w.selections.get(key)
        if hit is None:
            check_table, check_object, check_self, ignore_hand_object, ignore_hand_table = key
            wanted = {"table": check_table, "object": check_object, "self": check_self}
            sel = [
                p for p in self._w.pairs
                if wanted[p.category] and not (ignore_hand_object and p.hand_object)
                and not (ignore_hand_table and p.hand and p.category == "table")
            ]  # fmt: skip
            hit = self._w.selections[key] = (sel, np.array([p.index for p in sel], dtype=np.intp))
        return hit

    def _manager(self, key: SelectionKey, margins: dict[str, float]) -> PairManager | None:
        """The :class:`PairManager` of the selection ``key`` with ``margins`` [m] applied (built once per
        selection; None when it cannot hold this world's geometries)."""
        w = self._w
        if key not in w.managers:
            pairs, _ = self._selected(key)
            try:
                w.managers[key] = PairManager(
                    self._model, w.gm, [p.index for p in pairs], {p.index: p.category for p in pairs}
                )
            except ValueError:
                w.managers[key] = None
        manager = w.managers[key]
        if manager is not None:
            manager.set_margins(margins)
        return manager

    def check(self, q: ArrayLike, **options: Unpack[CheckOptions]) -> CollisionReport:
        """Check the UR5 configuration ``q`` (``(6,)`` [rad]) with the :class:`CheckOptions` given (margins [m],
        pair groups, distances)."""
        qa = self.ur5.check_q(q)
        key, margins, distances = self._options(options)
        return self._check(qa, self._selected(key), margins, distances)

    def _options(self, o: CheckOptions) -> tuple[SelectionKey, dict[str, float], bool]:
        """The selection's flags, the margins [m] and whether distances are asked, from a call's options."""
        key = (o.get("check_table", True), o.get("check_object", True), o.get("check_self", True),
               o.get("ignore_hand_object", False), o.get("ignore_hand_table", False))  # fmt: skip
        margins = self._margins(o.get("margin"), o.get("table_margin"), o.get("self_margin"))
        return key, margins, o.get("distances", True)

    def _check(
        self,
        q: FloatArray,
        selection: tuple[list[PairInfo], NDArray[np.intp]],
        margins: dict[str, float],
        distances: bool,
        may_collide: NDArray[np.bool_] | None = None,
    ) -> CollisionReport:
        """Check the selected pairs at ``q`` [rad]: pairs the bounding volumes rule out (``may_collide``, computed
        here when not given) are not asked of coal, except for the distances when ``distances`` (then every table
        and object pair is measured)."""
        gm, gd = self._w.gm, self._w.gd
        self._apply_margins(margins)
        pairs, _ = selection
        if may_collide is None:
            may_collide = self._may_collide(q[None, :], selection, margins)[0]
        pin.forwardKinematics(self._model, self._data, q)
        pin.updateGeometryPlacements(self._model, self._data, gm, gd)
        hits: list[tuple[str, str]] = []
        cats: set[str] = set()
        # smallest distances: [arm+hand vs table, arm+hand vs object, hand vs table, hand vs object]
        dmin: list[float | None] = [None, None, None, None]
        maybe_pairs = may_collide.tolist()
        asked = range(len(pairs)) if distances else np.flatnonzero(may_collide).tolist()
        for k in asked:
            p, maybe = pairs[k], maybe_pairs[k]
            if not maybe and not (distances and p.category != "self"):
                continue
            if maybe and pin.computeCollision(gm, gd, p.index):
                hits.append(p.names)
                cats.add(p.category)
            if distances and p.category != "self":
                d = float(pin.computeDistance(gm, gd, p.index).min_distance)
                slot = 0 if p.category == "table" else 1
                dmin[slot] = min_optional(dmin[slot], d)
                if p.hand:
                    dmin[slot + 2] = min_optional(dmin[slot + 2], d)
        reasons = [REASON_OF[c] for c in CATEGORY_ORDER if c in cats]
        return make_report(bool(hits), hits, reasons, dmin)

    def _may_collide(
        self, Q: FloatArray, selection: tuple[list[PairInfo], NDArray[np.intp]], margins: dict[str, float]
    ) -> NDArray[np.bool_]:
        """Broad phase at every row of ``Q`` ``(W, 6)`` [rad]: ``(W, P)``, which selected pairs may collide."""
        _, idx = selection
        by_code = np.array([margins["table"], margins["object"], margins["self"]])
        w = self._w
        if w.broad_stale and w.obj is not None and w.object_id is not None:
            w.broad.move(w.object_id, w.gm.geometryObjects[w.object_id].placement, w.obj[0])
            w.broad_stale = False
        R, t = w.broad.joint_placements(self._model, self._data, Q)
        return w.broad.candidates(R, t, w.pair_a[idx], w.pair_b[idx], by_code[w.pair_category[idx]])

    def check_waypoints(self, qs: Sequence[ArrayLike] | ArrayLike, **options: Unpack[PathOptions]) -> CollisionReport:
        """Check a sequence of configurations (e.g. IK solutions along a straight approach).

        The report merges the waypoints: ``pairs``/``reasons`` of every colliding waypoint checked (only the
        first when ``stop_at_first``), ``waypoint`` = the first colliding index, the minimum distances over
        all checked waypoints, ``checked`` = how many were checked. Same options as :meth:`check`.
        """
        Q = np.asarray(qs, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != self.ur5.nq or Q.shape[0] < 1:
            raise InvalidInput(f"expected an (N, {self.ur5.nq}) array of configurations", field="qs")
        if not np.all(np.isfinite(Q)):
            raise InvalidInput("contains NaN or infinite values", field="qs")
        key, m, distances = self._options(options)
        selection = self._selected(key)
        stop_at_first = options.get("stop_at_first", True)
        hits: list[tuple[str, str]] = []
        reasons: list[str] = []
        first: int | None = None
        dmin: list[float | None] = [None, None, None, None]
        checked = 0
        # verdicts alone: one C++ call per waypoint, the pairs asked one by one only where it finds a collision
        manager = None if distances else self._manager(key, m)
        masks = None if manager is not None else self._may_collide(Q, selection, m)  # every waypoint at once
        for i, q in enumerate(Q):
            if manager is not None and not manager.collides(self._data, q):
                checked += 1
                continue
            if masks is not None and not distances and not masks[i].any():
                checked += 1  # nothing can collide here and no distance is asked: free
                continue
            r = self._check(q, selection, m, distances, None if masks is None else masks[i])
            checked += 1
            for j, d in enumerate(
                (
                    r.min_distance_table,
                    r.min_distance_object,
                    r.min_distance_hand_table,
                    r.min_distance_hand_object,
                )
            ):
                dmin[j] = min_optional(dmin[j], d)
            if r.in_collision:
                first = i if first is None else first
                hits.extend(h for h in r.pairs if h not in hits)
                reasons.extend(x for x in r.reasons if x not in reasons)
                if stop_at_first:
                    break
        reasons.sort(key=lambda x: [REASON_OF[c] for c in CATEGORY_ORDER].index(x))
        return make_report(first is not None, hits, reasons, dmin, waypoint=first, checked=checked)

    def check_path(
        self,
        q_from: ArrayLike,
        q_to: ArrayLike,
        steps: int = 10,
        **options: Unpack[PathOptions],
    ) -> CollisionReport:
        """Check ``steps + 1`` configurations interpolated linearly in joint space from ``q_from`` to ``q_to``
        (both ends included). The options are those of :meth:`check_waypoints`."""
        a = self.ur5.check_q(q_from, "q_from")
        b = self.ur5.check_q(q_to, "q_to")
        if steps < 1:
            raise InvalidInput("steps must be >= 1", field="steps", value=steps)
        s = np.linspace(0.0, 1.0, steps + 1)[:, None]
        return self.check_waypoints(a + s * (b - a), **options)
