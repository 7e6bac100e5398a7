"""Collision shapes of the hand and the object for coal: their kinds, sizes [m] (MuJoCo's size conventions) and
poses in the hand frame (= ``tool0``) or the world frame (UR5 ``base_link``, z up).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal, Protocol, TypeVar

import coal
import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput
from softsig_service.geometry.content_cache import ContentCache
from softsig_service.geometry.transforms import check_transform

FloatArray = NDArray[np.float64]
GeometryT = TypeVar("GeometryT", bound=coal.CollisionGeometry)

HandKind = Literal["box", "capsule", "sphere", "cylinder"]
ObjectKind = Literal["box", "cylinder", "sphere", "ellipsoid", "mesh"]

_HAND_SIZE_LEN: dict[str, int] = {"box": 3, "capsule": 2, "sphere": 1, "cylinder": 2}
_OBJECT_SIZE_LEN: dict[str, int] = {"box": 3, "cylinder": 2, "sphere": 1, "ellipsoid": 3, "mesh": 0}


def check_shape_size(kind: str, size: Sequence[float], expected: dict[str, int], field: str) -> tuple[float, ...]:
    if kind not in expected:
        raise InvalidInput(f"unknown shape kind {kind!r}", field=f"{field}.kind", value=kind, choices=expected)
    n = expected[kind]
    try:
        vals = tuple(float(v) for v in size)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("size must be numbers", field=f"{field}.size", value=size) from exc
    if len(vals) != n:
        raise InvalidInput(f"a {kind} needs {n} size values", field=f"{field}.size", value=list(vals))
    if not all(math.isfinite(v) and v > 0.0 for v in vals):
        raise InvalidInput("sizes must be finite and > 0 [m]", field=f"{field}.size", value=list(vals))
    return vals


@dataclass(frozen=True, eq=False)
class HandShape:
    """A primitive rigidly attached to the hand (= ``tool0``) frame, with MuJoCo's size conventions.

    Attributes:
        kind: ``"box"``, ``"capsule"``, ``"sphere"`` or ``"cylinder"``.
        size: [m] box: half-sizes (hx, hy, hz); capsule and cylinder: (radius, half-length), axis along the
            shape's local z (a capsule's half-length excludes its end caps, as in MuJoCo); sphere: (radius,).
        pose_in_hand: 4x4 pose of the shape's centre frame in the hand frame (default identity).
        name: optional label used in collision reports (``"hand:<name>"``; default ``"<kind><index>"``).
    """

    kind: HandKind
    size: tuple[float, ...]
    pose_in_hand: FloatArray = field(default_factory=lambda: np.eye(4))
    name: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", check_shape_size(self.kind, self.size, _HAND_SIZE_LEN, "hand_shape"))
        T = check_transform(self.pose_in_hand, field="hand_shape.pose_in_hand").copy()
        T.setflags(write=False)
        object.__setattr__(self, "pose_in_hand", T)

    def geometry(self) -> coal.CollisionGeometry:
        """The coal geometry of this shape (in its own centre frame)."""
        return coal_primitive(self.kind, self.size)


class ShapeSpec(Protocol):
    """What :meth:`CollisionWorld.set_object` needs of an object shape (MuJoCo size conventions).

    ``kind`` is one of box, cylinder, sphere, ellipsoid, mesh; ``size`` [m] is box half-sizes, cylinder
    (radius, half-length) with its axis along the shape's z, sphere (radius,), ellipsoid (rx, ry, rz) radii,
    and empty for a mesh; ``vertices`` ``(N, 3)`` [m] in the shape frame for a mesh (its convex hull is used).
    """

    @property
    def kind(self) -> str: ...

    @property
    def size(self) -> tuple[float, ...]: ...

    @property
    def vertices(self) -> FloatArray | None: ...

    # optional: ``content_key`` (str), a digest of the mesh's content; the hull is then built once per key


@dataclass(frozen=True, eq=False)
class ObjectShape:
    """A concrete :class:`ShapeSpec`: an object shape in its own frame (MuJoCo size conventions, [m])."""

    kind: ObjectKind
    size: tuple[float, ...] = ()
    vertices: FloatArray | None = None


_MESH_HULLS: ContentCache[coal.ConvexBase] = ContentCache(size=64)
"""coal convex hulls of meshes by content key (qhull on a 40k-vertex scan takes tens of milliseconds). A hull is
shared read-only by every collision world and thread."""


def coal_primitive(kind: str, size: Sequence[float]) -> coal.CollisionGeometry:
    """coal geometry from MuJoCo-style sizes (coal takes full box sides and full cylinder/capsule lengths)."""
    if kind == "box":
        return coal.Box(2.0 * size[0], 2.0 * size[1], 2.0 * size[2])
    if kind == "capsule":
        return coal.Capsule(size[0], 2.0 * size[1])
    if kind == "cylinder":
        return coal.Cylinder(size[0], 2.0 * size[1])
    if kind == "sphere":
        return coal.Sphere(size[0])
    if kind == "ellipsoid":
        return coal.Ellipsoid(size[0], size[1], size[2])
    raise InvalidInput(f"unknown shape kind {kind!r}", field="kind", value=kind)  # pragma: no cover


def local_aabb(geometry: GeometryT) -> GeometryT:
    """``geometry`` with its local AABB computed (``aabb_local``, ``aabb_center``, ``aabb_radius``, in its own frame
    [m]), once: coal leaves ``aabb_radius`` at -1 until then, and a 40k-vertex hull takes ~0.3 ms to bound."""
    if geometry.aabb_radius < 0.0:
        geometry.computeLocalAABB()
    return geometry


def convex_hull(points: ArrayLike, field: str = "vertices") -> coal.ConvexBase:
    """coal convex hull (qhull) of ``(N, 3)`` points [m]; :class:`InvalidInput` if they span no volume."""
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 4:
        raise InvalidInput("need an (N, 3) array with N >= 4", field=field, value=f"shape {P.shape}")
    if not np.all(np.isfinite(P)):
        raise InvalidInput("contains NaN or infinite values", field=field)
    centred = P - P.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[-1] <= 1e-9 * max(sv[0], 1e-12):
        raise InvalidInput("points are coplanar: their hull has no volume", field=field)
    v = coal.StdVec_Vec3s()
    v.extend(list(P))
    return coal.Convex.convexHull(v, False, "")


def object_geometry(shape: ShapeSpec, field: str = "object") -> coal.CollisionGeometry:
    """coal geometry of an object shape (see :class:`ShapeSpec`)."""
    kind = shape.kind
    if kind not in _OBJECT_SIZE_LEN:
        raise InvalidInput(f"unknown object kind {kind!r}", field=f"{field}.kind", value=kind, choices=_OBJECT_SIZE_LEN)
    if kind == "mesh":
        vertices = shape.vertices
        if vertices is None:
            raise InvalidInput("a mesh needs vertices", field=f"{field}.vertices")
        key = getattr(shape, "content_key", None)
        if key is None:
            return convex_hull(vertices, field=f"{field}.vertices")
        return _MESH_HULLS.get(str(key), lambda: local_aabb(convex_hull(vertices, field=f"{field}.vertices")))
    return coal_primitive(kind, check_shape_size(kind, shape.size, _OBJECT_SIZE_LEN, field))


# ----------------------------------------------------------------------------------------------------------
# report
# ----------------------------------------------------------------------------------------------------------
