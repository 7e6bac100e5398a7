"""Objects resting on the table: shapes, poses, principal horizontal axes, mass and friction.

Frames and units (DESIGN §3): the world frame is the UR5 ``base_link`` (z up) and the table top is the plane
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
    {"kind": "builtin",   "name": "box" | "apple" | "cylinder", ...}  the objects of DESIGN §7
    common keys: "mass": kg (> 0; required except for builtin), "friction": (> 0, default 1.0),
                 "name": str, "pose": {"x": m, "y": m, "yaw": rad, "z": m (optional centre height)}
                 (default pose x = 0.5, y = 0.0, yaw = 0.0: in front of the robot)

Malformed specs raise :class:`softsig_service.errors.InvalidInput` naming the field (``object.size[2]``) and,
for closed sets, the valid choices. Pure numpy.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput
from softsig_service.geometry.transforms import make_transform, rot_y, rot_z

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

ObjectKind = Literal["box", "cylinder", "sphere", "ellipsoid", "mesh"]
OBJECT_KINDS: tuple[str, ...] = ("box", "cylinder", "sphere", "ellipsoid", "mesh")
BUILTIN_NAMES: tuple[str, ...] = ("box", "apple", "cylinder")
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


# ----------------------------------------------------------------------------------------------------------
# validation helpers
# ----------------------------------------------------------------------------------------------------------


def _number(v: Any, field: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
        raise InvalidInput("expected a number", field=field, value=v)
    f = float(v)
    if not math.isfinite(f):
        raise InvalidInput("NaN or infinite value", field=field, value=v)
    return f


def _positive(v: Any, field: str) -> float:
    f = _number(v, field)
    if f <= 0.0:
        raise InvalidInput("must be > 0", field=field, value=v)
    return f


def _positive_list(v: Any, n: int, field: str) -> tuple[float, ...]:
    if isinstance(v, str | bytes | Mapping) or not isinstance(v, Sequence | np.ndarray):
        raise InvalidInput(f"expected a list of {n} numbers", field=field, value=v)
    if len(v) != n:
        raise InvalidInput(f"expected {n} values, got {len(v)}", field=field, value=list(v))
    return tuple(_positive(x, f"{field}[{i}]") for i, x in enumerate(v))


def _check_mesh(vertices: ArrayLike, faces: ArrayLike, field: str) -> tuple[FloatArray, IntArray]:
    try:
        V = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("vertices must be numbers", field=f"{field}.vertices") from exc
    if V.ndim != 2 or V.shape[1] != 3 or V.shape[0] < 4:
        raise InvalidInput(
            "expected an (N, 3) vertex array, N >= 4", field=f"{field}.vertices", value=f"shape {V.shape}"
        )
    if not np.all(np.isfinite(V)):
        raise InvalidInput("NaN or infinite vertex coordinates", field=f"{field}.vertices")
    try:
        F_raw = np.asarray(faces)
    except (TypeError, ValueError) as exc:  # pragma: no cover - ragged input
        raise InvalidInput("faces must be integer triples", field=f"{field}.faces") from exc
    if F_raw.ndim != 2 or F_raw.shape[1] != 3 or F_raw.shape[0] < 4:
        raise InvalidInput(
            "expected an (M, 3) face array, M >= 4", field=f"{field}.faces", value=f"shape {F_raw.shape}"
        )
    if F_raw.dtype.kind not in "iu" and not (
        F_raw.dtype.kind == "f" and np.all(np.isfinite(F_raw)) and np.all(F_raw == np.round(F_raw))
    ):
        raise InvalidInput("face indices must be integers", field=f"{field}.faces")
    F = F_raw.astype(np.int64)
    if F.min() < 0 or F.max() >= V.shape[0]:
        raise InvalidInput(
            f"face indices must lie in [0, {V.shape[0] - 1}]",
            field=f"{field}.faces",
            value=[int(F.min()), int(F.max())],
        )
    centred = V - V.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[-1] <= 1e-9 * max(float(sv[0]), 1e-12):
        raise InvalidInput("the mesh is flat or degenerate (no volume)", field=f"{field}.vertices")
    return V, F


def convex_hull_2d(points: ArrayLike) -> FloatArray:
    """Convex hull (counter-clockwise, no repeated end point) of 2D points ``(N, 2)`` (monotone chain)."""
    P = np.unique(np.asarray(points, dtype=np.float64), axis=0)
    if len(P) < 3:
        return P
    pts = sorted(map(tuple, P))

    def cross(o: tuple[float, ...], a: tuple[float, ...], b: tuple[float, ...]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, ...]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0.0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, ...]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0.0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def polygon_moments(poly: ArrayLike) -> tuple[float, FloatArray, FloatArray]:
    """Area [m^2], centroid ``(2,)`` [m] and central second-moment matrix ``(2, 2)`` [m^4] of a simple polygon
    given counter-clockwise (Green's theorem)."""
    P = np.asarray(poly, dtype=np.float64)
    x, y = P[:, 0], P[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    c = x * yn - xn * y
    area = 0.5 * float(c.sum())
    if abs(area) < 1e-18:
        raise InvalidInput("the footprint has no area", field="footprint")
    cx = float(((x + xn) * c).sum()) / (6.0 * area)
    cy = float(((y + yn) * c).sum()) / (6.0 * area)
    ixx = float(((x * x + x * xn + xn * xn) * c).sum()) / 12.0  # integral of x^2 dA
    iyy = float(((y * y + y * yn + yn * yn) * c).sum()) / 12.0
    ixy = float(((x * yn + 2.0 * x * y + 2.0 * xn * yn + xn * y) * c).sum()) / 24.0
    M = np.array([[ixx - area * cx * cx, ixy - area * cx * cy], [ixy - area * cx * cy, iyy - area * cy * cy]])
    return area, np.array([cx, cy]), M


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

    def __post_init__(self) -> None:
        if self.kind not in OBJECT_KINDS:
            raise InvalidInput(
                f"unknown object kind {self.kind!r}",
                field="object.kind",
                value=self.kind,
                choices=OBJECT_KINDS,
            )
        n = {"box": 3, "cylinder": 2, "sphere": 1, "ellipsoid": 3, "mesh": 0}[self.kind]
        dims = _positive_list(self.dimensions, n, "object.dimensions")
        object.__setattr__(self, "dimensions", dims)
        for f in ("mass", "friction"):
            object.__setattr__(self, f, _positive(getattr(self, f), f"object.{f}"))
        for f in ("x", "y", "yaw", "table_height"):
            object.__setattr__(self, f, _number(getattr(self, f), f"object.pose.{f}"))
        if self.standing and self.kind != "cylinder":
            raise InvalidInput("only a cylinder can be standing", field="object.standing", value=self.kind)
        if self.kind == "mesh":
            if self.vertices is None or self.faces is None:
                raise InvalidInput("a mesh needs vertices and faces", field="object.vertices")
            V, F = _check_mesh(self.vertices, self.faces, "object")
            lo, hi = V.min(axis=0), V.max(axis=0)
            V = V - 0.5 * (lo + hi)  # the object frame's origin is the centre of the bounding box
            V.setflags(write=False)
            F.setflags(write=False)
            object.__setattr__(self, "vertices", V)
            object.__setattr__(self, "faces", F)
        elif self.vertices is not None or self.faces is not None:
            raise InvalidInput("vertices and faces are for meshes only", field="object.vertices")
        if self.z is not None:
            zc = _number(self.z, "object.pose.z")
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

    @property
    def half_extents(self) -> FloatArray:
        """Half-sizes [m] of the object's bounding box along the object frame's x, y, z."""
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
    def _axes(self) -> tuple[FloatArray, float, float, bool]:
        """Major axis (2,) in the object frame, extent along it, extent across it [m], isotropic flag."""
        if self.kind == "mesh":
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
            if iso:
                return np.array([1.0, 0.0]), e1, e2, True
            return a1, e1, e2, False
        hx, hy, _ = self.half_extents
        ex, ey = 2.0 * float(hx), 2.0 * float(hy)
        if abs(ex - ey) <= _ISOTROPY_TOL:
            return np.array([1.0, 0.0]), ex, ey, True
        if ex > ey:
            return np.array([1.0, 0.0]), ex, ey, False
        return np.array([0.0, 1.0]), ey, ex, False

    # -- placement in the world -----------------------------------------------------------------------------

    @property
    def center(self) -> FloatArray:
        """Centre of the object [m] in the world frame."""
        zc = self.table_height + self.height / 2.0 if self.z is None else self.z
        return np.array([self.x, self.y, zc])

    @property
    def pose(self) -> FloatArray:
        """``T_world_object`` (4x4): object frame at the centre, rotated by ``yaw`` about world z."""
        return make_transform(rot_z(self.yaw), self.center)

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
        """The same object at another table pose (x, y [m], yaw [rad]), resting on the table."""
        return dataclasses.replace(self, x=x, y=y, yaw=yaw, z=None)

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
        return ShapePrimitive("mesh", (), self.vertices, self.faces)

    @property
    def primitive_in_object(self) -> FloatArray:
        """Pose (4x4) of the primitive frame in the object frame: a lying cylinder turns its z onto the x."""
        if self.kind == "cylinder" and not self.standing:
            return make_transform(rot_y(math.pi / 2.0))
        return np.eye(4)

    @property
    def primitive_pose(self) -> FloatArray:
        """Pose (4x4) ``T_world_primitive`` of :meth:`primitive`."""
        return self.pose @ self.primitive_in_object

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
            assert self.vertices is not None and self.faces is not None
            spec["vertices"] = self.vertices.tolist()
            spec["faces"] = self.faces.tolist()
        spec.update(mass=self.mass, friction=self.friction)
        if self.name:
            spec["name"] = self.name
        pose: dict[str, float] = {"x": self.x, "y": self.y, "yaw": self.yaw}
        if self.z is not None:
            pose["z"] = self.z
        spec["pose"] = pose
        return spec


# ----------------------------------------------------------------------------------------------------------
# constructors
# ----------------------------------------------------------------------------------------------------------


def box(
    size: Sequence[float],
    mass: float,
    *,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "box",
) -> TableObject:
    """A box of full sizes ``size`` = (sx, sy, sz) [m] along the object's x, y, z, resting on the table."""
    return TableObject("box", tuple(size), mass, friction, x, y, yaw, table_height, z, name=name)


def cylinder(
    radius: float,
    length: float,
    mass: float,
    *,
    standing: bool = False,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "cylinder",
) -> TableObject:
    """A cylinder of ``radius`` and ``length`` [m], lying with its axis along the object's x (centre at
    ``table_height + radius``), or ``standing`` with its axis vertical."""
    return TableObject(
        "cylinder", (radius, length), mass, friction, x, y, yaw, table_height, z, standing=standing, name=name
    )


def sphere(
    radius: float,
    mass: float,
    *,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "sphere",
) -> TableObject:
    """A sphere of ``radius`` [m] resting on the table."""
    return TableObject("sphere", (radius,), mass, friction, x, y, yaw, table_height, z, name=name)


def ellipsoid(
    radii: Sequence[float],
    mass: float,
    *,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "ellipsoid",
) -> TableObject:
    """An ellipsoid with semi-axes ``radii`` = (rx, ry, rz) [m] along the object's x, y, z, on the table."""
    return TableObject("ellipsoid", tuple(radii), mass, friction, x, y, yaw, table_height, z, name=name)


def mesh(
    vertices: ArrayLike,
    faces: ArrayLike,
    mass: float,
    *,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "mesh",
) -> TableObject:
    """A triangle mesh (vertices ``(N, 3)`` [m], faces ``(M, 3)`` indices), z up as given; the object frame is
    re-centred on the vertices' bounding box and the mesh rests on the table."""
    try:
        V = np.asarray(vertices, dtype=np.float64)
        F = np.asarray(faces)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("vertices/faces must be rectangular number arrays", field="object.vertices") from exc
    return TableObject("mesh", (), mass, friction, x, y, yaw, table_height, z, vertices=V, faces=F, name=name)


_BUILTINS: dict[str, dict[str, Any]] = {
    # DESIGN §7: default objects of the reference experiment (no sizes are published for the paper's objects)
    "box": {"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15},
    "apple": {"kind": "ellipsoid", "radii": [0.040, 0.040, 0.036], "mass": 0.18},
    "cylinder": {"kind": "cylinder", "radius": 0.03, "length": 0.16, "orientation": "lying", "mass": 0.20},
}


def builtin_object(
    name: str,
    *,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
) -> TableObject:
    """One of the built-in objects of DESIGN §7 at a table pose: ``"box"`` (0.16 x 0.06 x 0.05 m, 0.15 kg),
    ``"apple"`` (ellipsoid radii 0.040, 0.040, 0.036 m, 0.18 kg) or ``"cylinder"`` (radius 0.03 m, length
    0.16 m, lying, 0.20 kg). Raises :class:`InvalidInput` listing the choices for another name."""
    if name not in _BUILTINS:
        raise InvalidInput(f"unknown built-in object {name!r}", field="object.name", value=name, choices=BUILTIN_NAMES)
    spec = dict(_BUILTINS[name], name=name, pose={"x": x, "y": y, "yaw": yaw})
    return object_from_json(spec, table_height=table_height)


_COMMON_KEYS = frozenset({"kind", "mass", "friction", "name", "pose"})
_KIND_KEYS: dict[str, frozenset[str]] = {
    "box": frozenset({"size"}),
    "cylinder": frozenset({"radius", "length", "orientation"}),
    "sphere": frozenset({"radius"}),
    "ellipsoid": frozenset({"radii"}),
    "mesh": frozenset({"vertices", "faces"}),
    "builtin": frozenset(),
}
_POSE_KEYS = frozenset({"x", "y", "yaw", "z"})


def object_from_json(spec: Mapping[str, Any], *, table_height: float = 0.0, field: str = "object") -> TableObject:
    """Build a :class:`TableObject` from a JSON spec (schema in the module docstring).

    ``field`` is the spec's dotted path in the request, used in error messages.
    """
    if not isinstance(spec, Mapping):
        raise InvalidInput("expected an object spec (a JSON object)", field=field, value=spec)
    kind = spec.get("kind")
    if kind not in _KIND_KEYS:
        raise InvalidInput(f"unknown object kind {kind!r}", field=f"{field}.kind", value=kind, choices=_KIND_KEYS)
    allowed = _COMMON_KEYS | _KIND_KEYS[kind]
    unknown = sorted(set(spec) - allowed)
    if unknown:
        raise InvalidInput(f"unknown keys {unknown} for a {kind}", field=field, value=unknown, choices=allowed)

    def need(key: str) -> Any:
        if key not in spec:
            raise InvalidInput(f"a {kind} needs {key!r}", field=f"{field}.{key}")
        return spec[key]

    name = spec.get("name", "")
    if not isinstance(name, str):
        raise InvalidInput("name must be a string", field=f"{field}.name", value=name)

    if kind == "builtin":
        if name not in _BUILTINS:
            raise InvalidInput(
                f"unknown built-in object {name!r}", field=f"{field}.name", value=name, choices=BUILTIN_NAMES
            )
        base = dict(_BUILTINS[name])
        for k in ("mass", "friction", "pose"):
            if k in spec:
                base[k] = spec[k]
        base["name"] = name
        return object_from_json(base, table_height=table_height, field=field)

    pose = spec.get("pose", {})
    if not isinstance(pose, Mapping):
        raise InvalidInput("pose must be {x, y, yaw[, z]}", field=f"{field}.pose", value=pose)
    bad = sorted(set(pose) - _POSE_KEYS)
    if bad:
        raise InvalidInput(f"unknown pose keys {bad}", field=f"{field}.pose", value=bad, choices=_POSE_KEYS)
    x = _number(pose.get("x", DEFAULT_X), f"{field}.pose.x")
    y = _number(pose.get("y", DEFAULT_Y), f"{field}.pose.y")
    yaw = _number(pose.get("yaw", 0.0), f"{field}.pose.yaw")
    z = None if pose.get("z") is None else _number(pose["z"], f"{field}.pose.z")
    mass = _positive(need("mass"), f"{field}.mass")
    friction = _positive(spec.get("friction", DEFAULT_FRICTION), f"{field}.friction")
    th = _number(table_height, "table_height")
    common: dict[str, Any] = {
        "friction": friction,
        "x": x,
        "y": y,
        "yaw": yaw,
        "table_height": th,
        "z": z,
        "name": name or kind,
    }

    if kind == "box":
        return box(_positive_list(need("size"), 3, f"{field}.size"), mass, **common)
    if kind == "cylinder":
        orientation = spec.get("orientation", "lying")
        if orientation not in CYLINDER_ORIENTATIONS:
            raise InvalidInput(
                f"unknown cylinder orientation {orientation!r}",
                field=f"{field}.orientation",
                value=orientation,
                choices=CYLINDER_ORIENTATIONS,
            )
        r = _positive(need("radius"), f"{field}.radius")
        length = _positive(need("length"), f"{field}.length")
        return cylinder(r, length, mass, standing=orientation == "standing", **common)
    if kind == "sphere":
        return sphere(_positive(need("radius"), f"{field}.radius"), mass, **common)
    if kind == "ellipsoid":
        return ellipsoid(_positive_list(need("radii"), 3, f"{field}.radii"), mass, **common)
    V_raw, F_raw = need("vertices"), need("faces")
    try:
        V = np.asarray(V_raw, dtype=np.float64)
        F = np.asarray(F_raw)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("vertices/faces must be rectangular arrays", field=f"{field}.vertices") from exc
    _check_mesh(V, F, field)
    return mesh(V, F, mass, **common)
