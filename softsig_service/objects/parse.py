"""Objects from JSON (the schema in :mod:`softsig_service.objects.shape`) and the built-in objects of the
reference experiment (docs/design.md §7). Malformed specs raise
:class:`~softsig_service.errors.InvalidInput` naming the field.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import ValidationError

from softsig_service.errors import InvalidInput
from softsig_service.geometry.content_cache import ContentCache, content_digest
from softsig_service.objects.checks import check_mesh, check_number
from softsig_service.objects.cloud import CloudSolid, conservative_solid
from softsig_service.objects.constructors import box, cylinder, ellipsoid, mesh, sphere
from softsig_service.objects.frames import Frames, to_world, unit_quaternion
from softsig_service.objects.schema import OBJECT_SPEC, UNION_TAGS
from softsig_service.objects.segmentation import Segmentation
from softsig_service.objects.shape import (
    DEFAULT_X,
    DEFAULT_Y,
    HOUSEHOLD_NAMES,
    OBJECT_NAMES,
    TableObject,
)
from softsig_service.validation import invalid_input

_BUILTINS: dict[str, dict[str, Any]] = {
    # docs/design.md §7: default objects of the reference experiment (no sizes are published for the paper's objects)
    "box": {"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15},
    "apple": {"kind": "ellipsoid", "radii": [0.040, 0.040, 0.036], "mass": 0.18},
    "cylinder": {"kind": "cylinder", "radius": 0.03, "length": 0.16, "orientation": "lying", "mass": 0.20},
}
OBJECT_KINDS_JSON: tuple[str, ...] = tuple(sorted(UNION_TAGS))
"""The ``kind`` values of the object JSON."""


def builtin_object(
    name: str,
    *,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
) -> TableObject:
    """One of the built-in objects of docs/design.md §7 at a table pose: ``"box"`` (0.16 x 0.06 x 0.05 m, 0.15 kg),
    ``"apple"`` (ellipsoid radii 0.040, 0.040, 0.036 m, 0.18 kg) or ``"cylinder"`` (radius 0.03 m, length
    0.16 m, lying, 0.20 kg), or a shipped household mesh (:data:`HOUSEHOLD_NAMES`). Raises :class:`InvalidInput`
    listing the choices for another name."""
    if name not in OBJECT_NAMES:
        raise InvalidInput(f"unknown built-in object {name!r}", field="object.name", value=name, choices=OBJECT_NAMES)
    spec = {"kind": "builtin", "name": name, "pose": {"x": x, "y": y, "yaw": yaw}}
    return object_from_json(spec, table_height=table_height)


def object_from_json(
    spec: Mapping[str, Any], *, table_height: float = 0.0, frames: Frames | None = None, field: str = "object"
) -> TableObject:
    """Build a :class:`TableObject` from a JSON spec (schema in the module docstring).

    ``table_height`` [m]: the table top in ``base_link``. ``frames``: poses in ``base_link`` of the frames the spec
    may name in ``frame_id`` (:mod:`softsig_service.objects.frames`). ``field`` is the spec's dotted path in the
    request, used in error messages. A point cloud (``"points"``) becomes the mesh of its conservative solid
    (:mod:`softsig_service.objects.cloud`).
    """
    if not isinstance(spec, Mapping):
        raise InvalidInput("expected an object spec (a JSON object)", field=field, value=spec)
    kind = spec.get("kind")
    if kind not in OBJECT_KINDS_JSON:
        raise InvalidInput(
            f"unknown object kind {kind!r}", field=f"{field}.kind", value=kind, choices=OBJECT_KINDS_JSON
        )
    try:  # the one schema of objects (keys, types, ranges), shared with the REST API
        model = OBJECT_SPEC.validate_python(dict(spec))
    except ValidationError as exc:
        raise invalid_input(exc, field, UNION_TAGS) from None

    if kind == "builtin":
        if model.name in HOUSEHOLD_NAMES:
            from softsig_service.objects.household import household_json

            base = household_json(model.name)
        else:
            base = dict(_BUILTINS[model.name], name=model.name)
        base.update({k: spec[k] for k in ("mass", "friction", "pose") if k in spec})
        return object_from_json(base, table_height=table_height, field=field)
    if kind == "points":
        return _cloud_object(model, check_number(table_height, "table_height"), frames, field)
    if kind == "tabletop":
        return tabletop_objects(spec, frames, field)[0]
    if kind == "stored":
        raise InvalidInput("a stored object is found in the service's registry (POST /v1/objects)",
                           field=f"{field}.kind", value=kind)  # fmt: skip

    pose = model.pose
    if pose.orientation is not None:
        return _turned(model, check_number(table_height, "table_height"), field)
    common: dict[str, Any] = {
        "friction": model.friction,
        "x": pose.x,
        "y": pose.y,
        "yaw": pose.yaw,
        "table_height": check_number(table_height, "table_height"),
        "z": pose.z,
        "name": model.name or kind,
    }
    if kind == "box":
        return box(model.size, model.mass, **common)
    if kind == "cylinder":
        return cylinder(model.radius, model.length, model.mass, standing=model.orientation == "standing", **common)
    if kind == "sphere":
        return sphere(model.radius, model.mass, **common)
    if kind == "ellipsoid":
        return ellipsoid(model.radii, model.mass, **common)
    V, F = check_mesh(np.asarray(model.vertices, dtype=np.float64), np.asarray(model.faces), field)
    return mesh(V, F, model.mass, **common)


_SOLIDS: ContentCache[CloudSolid] = ContentCache(size=16)
"""Conservative solids by the digest of their points (in ``base_link``), table height and filter flag: a cloud sent
again (another strategy, another plan) is not filtered and hulled again."""


def _cloud_object(model: Any, table_height: float, frames: Frames | None, field: str) -> TableObject:
    """The mesh object of a point cloud's conservative solid, resting on the table."""
    points = to_world(np.asarray(model.points, dtype=np.float64), model.frame_id, frames, f"{field}.frame_id")
    flags = np.array([table_height, float(model.filter_outliers)])
    solid = _SOLIDS.get(
        content_digest(points, flags),
        lambda: conservative_solid(
            points, table_height, filter_outliers=model.filter_outliers, field=f"{field}.points"
        ),
    )
    return solid_object(solid, table_height, model.mass, model.friction, model.name or "points")


def solid_object(solid: CloudSolid, table_height: float, mass: float, friction: float, name: str) -> TableObject:
    """The mesh object of a conservative solid (vertices in ``base_link``), resting on the table."""
    lo, hi = solid.vertices.min(axis=0), solid.vertices.max(axis=0)
    centre = 0.5 * (lo + hi)
    return mesh(
        solid.vertices - centre, solid.faces, mass, friction=friction, x=float(centre[0]), y=float(centre[1]),
        yaw=0.0, table_height=table_height, name=name,
    )  # fmt: skip


_TABLETOPS: ContentCache[Segmentation] = ContentCache(size=8)
"""Segmentations by the digest of their points (in ``base_link``) and parameters."""


def segmentation_of(points: np.ndarray, params: Any, field: str) -> Segmentation:
    """The segmentation of ``points`` [m, base_link] with the ``plane_tolerance``, ``cluster_distance``,
    ``min_points`` and ``filter_outliers`` of ``params`` (a tabletop spec or a segmentation request), cached by
    content and parameters."""
    from softsig_service.objects.segmentation import segment_tabletop

    key = (params.plane_tolerance, params.cluster_distance, params.min_points, params.filter_outliers)

    def build() -> Segmentation:
        return segment_tabletop(points, plane_tolerance=key[0], cluster_distance=key[1], min_points=key[2],
                                filter_outliers=key[3], field=field)  # fmt: skip

    return _TABLETOPS.get(content_digest(points, np.array(key, dtype=np.float64)), build)


def tabletop_objects(
    spec: Mapping[str, Any], frames: Frames | None = None, field: str = "object"
) -> tuple[TableObject, list[TableObject], Segmentation]:
    """A ``tabletop`` spec's target (the cluster it picks, with its ``mass``, ``friction`` and ``name``), the other
    clusters as obstacles (mass and friction of the target), and the segmentation
    (:mod:`softsig_service.objects.segmentation`); every object rests on the table plane found."""
    from softsig_service.objects.segmentation import pick_target

    try:
        model = OBJECT_SPEC.validate_python(dict(spec))
    except ValidationError as exc:
        raise invalid_input(exc, field, UNION_TAGS) from None
    points = to_world(np.asarray(model.points, dtype=np.float64), model.frame_id, frames, f"{field}.frame_id")
    seg = segmentation_of(points, model, f"{field}.points")
    near = None if model.pick.near is None else np.array([model.pick.near.x, model.pick.near.y, model.pick.near.z])
    target = pick_target(seg, index=model.pick.index, near=near, field=f"{field}.pick")
    names = [(model.name or "target") if c.index == target else f"cluster_{c.index}" for c in seg.clusters]
    objects = [
        solid_object(c.solid, seg.height, model.mass, model.friction, name)
        for c, name in zip(seg.clusters, names, strict=True)
    ]
    return objects[target], [o for k, o in enumerate(objects) if k != target], seg


TURNED_SECTIONS = 48
"""Facets around a turned cylinder's axis (its mesh is within 0.2% of its radius, inside it)."""
TURNED_SUBDIVISIONS = 3
"""Subdivisions of the icosphere of a turned sphere or ellipsoid (642 vertices)."""


def _turned(model: Any, table_height: float, field: str) -> TableObject:
    """The object of a spec whose pose has an ``orientation``: its shape in its own frame (a primitive as a mesh:
    exact for a box, :data:`TURNED_SECTIONS` facets around a cylinder, an icosphere of :data:`TURNED_SUBDIVISIONS`
    for a sphere or ellipsoid), turned by the quaternion and placed at (x, y) and the given centre height ``z`` or
    resting on the table; a mesh with vertical z and yaw 0 from then on."""
    import trimesh

    pose = model.pose
    if pose.yaw != 0.0:
        raise InvalidInput("give yaw or orientation, not both", field=f"{field}.pose.yaw", value=pose.yaw)
    from softsig_service.geometry.quaternions import quat_to_matrix

    R = quat_to_matrix(unit_quaternion(pose.orientation.model_dump(), f"{field}.pose.orientation"))
    kind = model.kind
    if kind == "box":
        shape = trimesh.creation.box(extents=model.size)
    elif kind == "cylinder":
        shape = trimesh.creation.cylinder(radius=model.radius, height=model.length, sections=TURNED_SECTIONS)
        if model.orientation == "lying":  # the object's x is a lying cylinder's axis
            shape.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    elif kind in ("sphere", "ellipsoid"):
        shape = trimesh.creation.icosphere(subdivisions=TURNED_SUBDIVISIONS)
        shape.apply_scale(model.radius if kind == "sphere" else np.asarray(model.radii))
    else:
        V0, F0 = check_mesh(np.asarray(model.vertices, dtype=np.float64), np.asarray(model.faces), field)
        shape = trimesh.Trimesh(V0 - 0.5 * (V0.min(axis=0) + V0.max(axis=0)), F0, process=False)
    own_vertices = np.asarray(shape.vertices, dtype=np.float64).reshape(-1, 3)
    own = np.ptp(own_vertices, axis=0) if len(own_vertices) else np.zeros(3)  # its sizes along its own x, y, z
    major, minor = (0, 1) if own[0] >= own[1] else (1, 0)
    axes = R[:, [major, minor, 2]]
    V = np.asarray(shape.vertices, dtype=np.float64) @ R.T
    lo, hi = V.min(axis=0), V.max(axis=0)
    centre = 0.5 * (lo + hi)
    return mesh(
        V - centre, np.asarray(shape.faces), model.mass, friction=model.friction, x=pose.x, y=pose.y, yaw=0.0,
        table_height=table_height, z=pose.z, name=model.name or kind, own_axes=axes,
    )  # fmt: skip
