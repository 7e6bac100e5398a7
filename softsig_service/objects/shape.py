"""Objects resting on the table: shapes, poses, principal horizontal axes, mass and friction.

Frames and units (docs/design.md §3): the world frame is the UR5 ``base_link`` (z up) and the table top is the plane
``z = table_height``. The **object frame** has its origin at the object's centre (for a mesh: the centre of
the vertices' bounding box) and its z axis vertical; ``yaw`` [rad] is its rotation about world z. A box's
size is (x, y, z) in that frame; a lying cylinder's axis is the object's x, a standing cylinder's is its z.
Lengths in [m], masses in [kg], friction is the (dimensionless) sliding coefficient.

An object is placed by ``(x, y, yaw)``; its centre height is derived so that it rests on the table
(``z = table_height + height / 2``; for the lying cylinder that is ``table_height + radius``). An explicit
centre height may be given (e.g. an object held above the table) but never one that sinks it below the table.

Principal horizontal axes: ``o1`` (major) and ``o2`` (minor) are unit vectors of the world's xy plane along
the longest and shortest horizontal extent of the object's footprint (its projection on the table), with
``o2 = z x o1`` so that ``(o1, o2, z)`` is right-handed. They are axes: their sign carries no meaning. For a
mesh they come from the second moments of area of the footprint (the convex hull of the projected vertices),
i.e. a PCA of the footprint. A round footprint (sphere, the apple, a standing cylinder, a square box) has no
preferred axis: ``footprint_isotropic`` is then True and ``o1`` is the object's x.

JSON schema of :func:`object_from_json` (unknown keys are rejected)::

    {"kind": "box",       "size": [sx, sy, sz],                ...}   full side lengths [m]
    {"kind": "cylinder",  "radius": r, "length": l,
                          "orientation": "lying" | "standing", ...}   default lying (axis = object x)
    {"kind": "sphere",    "radius": r,                         ...}
    {"kind": "ellipsoid", "radii": [rx, ry, rz],               ...}   semi-axes [m]
    {"kind": "mesh",      "vertices": [[x, y, z], ...],
                          "faces": [[i, j, k], ...],           ...}   triangles, 0-based vertex indices
    {"kind": "points",    "points": [[x, y, z], ...], "frame_id": "base_link",
                          "filter_outliers": true,             ...}   a segmented cloud: planned as its conservative
                                                                      solid, a mesh (objects/cloud.py, docs/objects.md)
    {"kind": "builtin",   "name": "box" | "apple" | "cylinder", ...}  the objects of docs/design.md §7, or
                          "mug" | "banana" | "power_drill" | "mustard_bottle": real meshes (objects/household.py)
    common keys: "mass": kg (> 0; required except for builtin), "friction": (> 0, default 1.0),
                 "name": str, "pose": {"x": m, "y": m, "yaw": rad, "z": m (optional centre height)}
                 (default pose x = 0.5, y = 0.0, yaw = 0.0: in front of the robot)

Malformed specs raise :class:`softsig_service.errors.InvalidInput` naming the field (``object.size[2]``) and,
for closed sets, the valid choices. Pure numpy.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import json
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput
from softsig_service.geometry.content_cache import ContentCache, content_digest
from softsig_service.geometry.transforms import make_transform, rot_y, rot_z
from softsig_service.objects.checks import check_angle, check_mesh, check_number, check_positive, check_positive_list
from softsig_service.objects.footprint import convex_hull_2d, polygon_moments

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

ObjectKind = Literal["box", "cylinder", "sphere", "ellipsoid", "mesh"]
OBJECT_KINDS: tuple[str, ...] = ("box", "cylinder", "sphere", "ellipsoid", "mesh")
BUILTIN_NAMES: tuple[str, ...] = ("box", "apple", "cylinder")
"""The objects of the reference experiment (docs/design.md §7, Table I)."""
HOUSEHOLD_NAMES: tuple[str, ...] = ("mug", "banana", "power_drill", "mustard_bottle")
"""Real household objects shipped as meshes (:mod:`softsig_service.objects.household`)."""
OBJECT_NAMES: tuple[str, ...] = (*BUILTIN_NAMES, *HOUSEHOLD_NAMES)
"""Every name a ``{"kind": "builtin"}`` object may have."""
CYLINDER_ORIENTATIONS: tuple[str, ...] = ("lying", "standing")

DEFAULT_FRICTION = 1.0
"""Sliding friction coefficient when none is given (MuJoCo's default)."""
DEFAULT_X = 0.5
"""Default object position x [m] in the world frame (in front of the UR5)."""
DEFAULT_Y = 0.0
"""Default object position y [m] in the world frame."""

_ISOTROPY_TOL = 1e-9
"""Horizontal extents equal within this [m] make a round (isotropic) footprint."""
_BELOW_TABLE_TOL = 1e-9
"""How far [m] an object's bottom may dip below the table top (rounding) before it counts as below."""

_LYING_CYLINDER = make_transform(rot_y(math.pi / 2.0))
"""Pose of a lying cylinder's primitive frame (axis = z) in the object frame (axis = x)."""
_LYING_CYLINDER.setflags(write=False)

_MESH_AXES: ContentCache[tuple[FloatArray, float, float, bool]] = ContentCache(size=64)
"""Principal horizontal axes of meshes, by content digest (the footprint hull of a scan takes ~0.1 s)."""


@dataclass(frozen=True, eq=False)
class ShapePrimitive:
    """An object's shape in its own primitive frame, with MuJoCo's size conventions (also coal's shape input).

    ``size`` [m]: box half-sizes (hx, hy, hz); cylinder (radius, half-length) with its axis along the
    primitive's z; sphere (radius,); ellipsoid radii (rx, ry, rz); empty for a mesh, whose ``vertices``
    ``(N, 3)`` [m] and ``faces`` ``(M, 3)`` are given in the object frame. Pose the primitive in the world
    with :attr:`TableObject.primitive_pose`.
    """

    kind: str
    size: tuple[float, ...]
    vertices: FloatArray | None = None
    faces: IntArray | None = None
    content_key: str | None = None
    """A mesh's content digest (:attr:`TableObject.content_digest`): geometry built from it is cached by it."""


# ----------------------------------------------------------------------------------------------------------
# the object
# ----------------------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class TableObject:
    """An object on the table. Build it with :func:`box`, :func:`cylinder`, :func:`sphere`, :func:`ellipsoid`,
    :func:`mesh`, :func:`builtin_object` or :func:`object_from_json` (they validate their input).

    Attributes:
        kind: box, cylinder, sphere, ellipsoid or mesh.
        dimensions: [m] box (sx, sy, sz) full sizes; cylinder (radius, length); sphere (radius,); ellipsoid
            radii (rx, ry, rz); mesh: () (see ``vertices``).
        mass: [kg]. friction: sliding friction coefficient.
        x, y: position [m] of the object's centre in the world. yaw: rotation [rad] about world z.
        table_height: z [m] of the table top.
        z: centre height [m] in the world, or None to rest on the table.
        standing: cylinder only: axis vertical (object z) instead of lying along the object x.
        vertices, faces: mesh only: ``(N, 3)`` [m] in the object frame (centred on their bounding box) and
            ``(M, 3)`` vertex indices.
        name: a label (``"box"``, ``"apple"``...).
    """

    kind: ObjectKind
    dimensions: tuple[float, ...]
    mass: float
    friction: float = DEFAULT_FRICTION
    x: float = DEFAULT_X
    y: float = DEFAULT_Y
    yaw: float = 0.0
    table_height: float = 0.0
    z: float | None = None
    standing: bool = False
    vertices: FloatArray | None = None
    faces: IntArray | None = None
    name: str = ""
    own_axes: FloatArray | None = None
    """For an object given with a full orientation: its own major, minor and up axes in base_link (3x3, columns;
    unit), before its shape became a mesh with vertical z. None for an object resting upright."""

    def __post_init__(self) -> None:
        if self.kind not in OBJECT_KINDS:
            raise InvalidInput(
                f"unknown object kind {self.kind!r}",
                field="object.kind",
                value=self.kind,
                choices=OBJECT_KINDS,
            )
        n = {"box": 3, "cylinder": 2, "sphere": 1, "ellipsoid": 3, "mesh": 0}[self.kind]
        dims = check_positive_list(self.dimensions, n, "object.dimensions")
        object.__setattr__(self, "dimensions", dims)
        for f in ("mass", "friction"):
            object.__setattr__(self, f, check_positive(getattr(self, f), f"object.{f}"))
        for f in ("x", "y", "yaw", "table_height"):
            object.__setattr__(self, f, check_number(getattr(self, f), f"object.pose.{f}"))
        check_angle(self.yaw, "object.pose.yaw")
        if self.standing and self.kind != "cylinder":
            raise InvalidInput("only a cylinder can be standing", field="object.standing", value=self.kind)
        if self.kind == "mesh":
            if self.vertices is None or self.faces is None:
                raise InvalidInput("a mesh needs vertices and faces", field="object.vertices")
            V, F = check_mesh(self.vertices, self.faces, "object")
            lo, hi = V.min(axis=0), V.max(axis=0)
            V = V - 0.5 * (lo + hi)  # the object frame's origin is the centre of the bounding box
            V.setflags(write=False)
            F.setflags(write=False)
            object.__setattr__(self, "vertices", V)
            object.__setattr__(self, "faces", F)
        elif self.vertices is not None or self.faces is not None:
            raise InvalidInput("vertices and faces are for meshes only", field="object.vertices")
        if self.z is not None:
            zc = check_number(self.z, "object.pose.z")
            object.__setattr__(self, "z", zc)
            if zc - self.height / 2.0 < self.table_height - _BELOW_TABLE_TOL:
                raise InvalidInput(
                    f"the object's bottom (z = {zc - self.height / 2.0:.4f} m) is below the table top "
                    f"(z = {self.table_height:.4f} m)",
                    field="object.pose.z",
                    value=zc,
                )
        _ = self._axes  # computed now so that a degenerate footprint fails at construction

    # -- geometry in the object frame ------------------------------------------------------------------------

    @functools.cached_property
    def half_extents(self) -> FloatArray:
        """Half-sizes [m] of the object's bounding box along the object frame's x, y, z (read-only; computed once:
        a mesh's takes a pass over its vertices)."""
        h = np.array(self._half_extents(), dtype=np.float64)
        h.setflags(write=False)
        return h

    def _half_extents(self) -> FloatArray:
        d = self.dimensions
        if self.kind == "box":
            return 0.5 * np.array(d)
        if self.kind == "cylinder":
            r, length = d
            return np.array([r, r, 0.5 * length]) if self.standing else np.array([0.5 * length, r, r])
        if self.kind == "sphere":
            return np.full(3, d[0])
        if self.kind == "ellipsoid":
            return np.array(d)
        assert self.vertices is not None
        return np.asarray(self.vertices.max(axis=0), dtype=np.float64)

    @property
    def height(self) -> float:
        """Vertical size [m] (for the lying cylinder: its diameter)."""
        return float(2.0 * self.half_extents[2])

    @functools.cached_property
    def content_digest(self) -> str | None:
        """A mesh's digest of its (re-centred) vertices and faces, None for the other kinds: the key under which
        geometry built from the mesh (principal axes, collision hull) is cached."""
        if self.vertices is None or self.faces is None:
            return None
        return content_digest(self.vertices, self.faces)

    @functools.cached_property
    def _axes(self) -> tuple[FloatArray, float, float, bool]:
        """Major axis (2,) in the object frame, extent along it, extent across it [m], isotropic flag."""
        if self.kind == "mesh":
            assert self.content_digest is not None
            return _MESH_AXES.get(self.content_digest, self._mesh_axes)
        hx, hy, _ = self.half_extents
        ex, ey = 2.0 * float(hx), 2.0 * float(hy)
        if abs(ex - ey) <= _ISOTROPY_TOL:
            return np.array([1.0, 0.0]), ex, ey, True
        if ex > ey:
            return np.array([1.0, 0.0]), ex, ey, False
        return np.array([0.0, 1.0]), ey, ex, False

    def _mesh_axes(self) -> tuple[FloatArray, float, float, bool]:
        """:attr:`_axes` of a mesh: second moments of area of its footprint's convex hull."""
        assert self.vertices is not None
        hull = convex_hull_2d(self.vertices[:, :2])
        if len(hull) < 3:
            raise InvalidInput("the mesh's footprint has no area", field="object.vertices")
        _, _, M = polygon_moments(hull)
        w, U = np.linalg.eigh(M)
        a1 = U[:, 1]
        if a1[0] < -1e-12 or (abs(a1[0]) <= 1e-12 and a1[1] < 0.0):
            a1 = -a1
        a2 = np.array([-a1[1], a1[0]])
        e1 = float(np.ptp(hull @ a1))
        e2 = float(np.ptp(hull @ a2))
        iso = bool(abs(w[1] - w[0]) <= 1e-9 * max(abs(w[1]), 1e-30))
        axis = np.array([1.0, 0.0]) if iso else np.array(a1, dtype=np.float64)
        axis.setflags(write=False)  # shared by every object with this mesh
        return axis, e1, e2, iso

    # -- placement in the world -----------------------------------------------------------------------------

    @property
    def center(self) -> FloatArray:
        """Centre of the object [m] in the world frame."""
        zc = self.table_height + self.height / 2.0 if self.z is None else self.z
        return np.array([self.x, self.y, zc])

    @property
    def pose(self) -> FloatArray:
        """``T_world_object`` (4x4): object frame at the centre, rotated by ``yaw`` about world z."""
        T = np.eye(4)
        T[:3, :3] = rot_z(self.yaw)  # a rotation by construction: not checked again
        T[:3, 3] = self.center
        return T

    @property
    def o1(self) -> FloatArray:
        """Major horizontal axis of the footprint, unit ``(3,)`` in the world frame."""
        a1 = self._axes[0]
        return rot_z(self.yaw) @ np.array([a1[0], a1[1], 0.0])

    @property
    def o2(self) -> FloatArray:
        """Minor horizontal axis of the footprint, ``z x o1``, unit ``(3,)`` in the world frame."""
        o1 = self.o1
        return np.array([-o1[1], o1[0], 0.0])

    @property
    def extent_major(self) -> float:
        """Footprint width [m] along ``o1``."""
        return self._axes[1]

    @property
    def extent_minor(self) -> float:
        """Footprint width [m] along ``o2`` (the closing width of a grasp across the object)."""
        return self._axes[2]

    @property
    def footprint_isotropic(self) -> bool:
        """Whether the footprint has no preferred horizontal axis (then ``o1`` is the object's x)."""
        return self._axes[3]

    @property
    def top_z(self) -> float:
        """Height [m] of the object's top in the world."""
        return float(self.center[2] + self.height / 2.0)

    def with_pose(self, x: float, y: float, yaw: float = 0.0) -> TableObject:
        """The same object at another table pose (x, y [m], yaw [rad]), resting on the table.

        Only the pose is checked: the shape was validated when this object was built, and what was derived from it
        (principal axes, a mesh's digest) is kept, so moving a 40k-vertex mesh costs no more than moving a box.
        """
        pose = {f: check_number(v, f"object.pose.{f}") for f, v in (("x", x), ("y", y), ("yaw", yaw))}
        moved = copy.copy(self)
        for f, v in pose.items():
            object.__setattr__(moved, f, v)
        object.__setattr__(moved, "z", None)
        return moved

    # -- shape for collision checking and simulation ------------------------------------------------------

    def primitive(self) -> ShapePrimitive:
        """The shape with MuJoCo/coal conventions (cylinder axis = primitive z); pose it with
        :attr:`primitive_pose`."""
        d = self.dimensions
        if self.kind == "box":
            return ShapePrimitive("box", (d[0] / 2.0, d[1] / 2.0, d[2] / 2.0))
        if self.kind == "cylinder":
            return ShapePrimitive("cylinder", (d[0], d[1] / 2.0))
        if self.kind == "sphere":
            return ShapePrimitive("sphere", (d[0],))
        if self.kind == "ellipsoid":
            return ShapePrimitive("ellipsoid", tuple(d))
        return ShapePrimitive("mesh", (), self.vertices, self.faces, self.content_digest)

    @property
    def primitive_in_object(self) -> FloatArray:
        """Pose (4x4) of the primitive frame in the object frame: a lying cylinder turns its z onto the x."""
        if self.kind == "cylinder" and not self.standing:
            return _LYING_CYLINDER.copy()
        return np.eye(4)

    @property
    def primitive_pose(self) -> FloatArray:
        """Pose (4x4) ``T_world_primitive`` of :meth:`primitive`."""
        return self.pose @ self.primitive_in_object

    @functools.cached_property
    def _mesh_json(self) -> dict[str, list[list[float]] | list[list[int]]]:
        """A mesh's ``vertices`` and ``faces`` as JSON lists, built once per object (read-only: shared by every
        :meth:`to_json` of this object and of its moved copies)."""
        assert self.vertices is not None and self.faces is not None
        return {"vertices": self.vertices.tolist(), "faces": self.faces.tolist()}

    @functools.cached_property
    def shape_digest(self) -> str:
        """SHA-256 (hex) of what the object is, wherever it stands: its JSON spec without pose and name (kind,
        dimensions [m], mass [kg], friction). Two objects with the same digest grasp alike; a capture model or a
        stiffness signature of one holds for the other."""
        spec = {k: v for k, v in self.to_json().items() if k not in ("pose", "name")}
        text = json.dumps(spec, sort_keys=True, separators=(",", ":"), allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()

    def to_json(self) -> dict[str, Any]:
        """The JSON spec of this object (see the module docstring); ``object_from_json`` reads it back."""
        d = self.dimensions
        spec: dict[str, Any] = {"kind": self.kind}
        if self.kind == "box":
            spec["size"] = list(d)
        elif self.kind == "cylinder":
            spec.update(radius=d[0], length=d[1], orientation="standing" if self.standing else "lying")
        elif self.kind == "sphere":
            spec["radius"] = d[0]
        elif self.kind == "ellipsoid":
            spec["radii"] = list(d)
        else:
            spec.update(self._mesh_json)
        spec.update(mass=self.mass, friction=self.friction)
        if self.name:
            spec["name"] = self.name
        pose: dict[str, float] = {"x": self.x, "y": self.y, "yaw": self.yaw}
        if self.z is not None:
            pose["z"] = self.z
        spec["pose"] = pose
        return spec
