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
from softsig_service.objects.checks import check_mesh, check_number, check_positive, check_positive_list
from softsig_service.objects.constructors import box, cylinder, ellipsoid, mesh, sphere
from softsig_service.objects.schema import OBJECT_SPEC, UNION_TAGS
from softsig_service.objects.shape import (
    BUILTIN_NAMES,
    CYLINDER_ORIENTATIONS,
    DEFAULT_FRICTION,
    DEFAULT_X,
    DEFAULT_Y,
    TableObject,
)
from softsig_service.validation import invalid_input

_BUILTINS: dict[str, dict[str, Any]] = {
    # docs/design.md §7: default objects of the reference experiment (no sizes are published for the paper's objects)
    "box": {"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15},
    "apple": {"kind": "ellipsoid", "radii": [0.040, 0.040, 0.036], "mass": 0.18},
    "cylinder": {"kind": "cylinder", "radius": 0.03, "length": 0.16, "orientation": "lying", "mass": 0.20},
}
OBJECT_KINDS_JSON: tuple[str, ...] = ("box", "builtin", "cylinder", "ellipsoid", "mesh", "sphere")
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
    0.16 m, lying, 0.20 kg). Raises :class:`InvalidInput` listing the choices for another name."""
    if name not in _BUILTINS:
        raise InvalidInput(f"unknown built-in object {name!r}", field="object.name", value=name, choices=BUILTIN_NAMES)
    spec = dict(_BUILTINS[name], name=name, pose={"x": x, "y": y, "yaw": yaw})
    return object_from_json(spec, table_height=table_height)


def object_from_json(spec: Mapping[str, Any], *, table_height: float = 0.0, field: str = "object") -> TableObject:
    """Build a :class:`TableObject` from a JSON spec (schema in the module docstring).

    ``field`` is the spec's dotted path in the request, used in error messages.
    """
    if not isinstance(spec, Mapping):
        raise InvalidInput("expected an object spec (a JSON object)", field=field, value=spec)
    kind = spec.get("kind")
    if kind not in OBJECT_KINDS_JSON:
        raise InvalidInput(
            f"unknown object kind {kind!r}", field=f"{field}.kind", value=kind, choices=OBJECT_KINDS_JSON
        )
    try:  # the one schema of objects (keys, types, ranges), shared with the REST API
        OBJECT_SPEC.validate_python(dict(spec))
    except ValidationError as exc:
        raise invalid_input(exc, field, UNION_TAGS) from None

    def need(key: str) -> Any:
        return spec[key]

    name = spec.get("name", "")

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
    x = check_number(pose.get("x", DEFAULT_X), f"{field}.pose.x")
    y = check_number(pose.get("y", DEFAULT_Y), f"{field}.pose.y")
    yaw = check_number(pose.get("yaw", 0.0), f"{field}.pose.yaw")
    z = None if pose.get("z") is None else check_number(pose["z"], f"{field}.pose.z")
    mass = check_positive(need("mass"), f"{field}.mass")
    friction = check_positive(spec.get("friction", DEFAULT_FRICTION), f"{field}.friction")
    th = check_number(table_height, "table_height")
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
        return box(check_positive_list(need("size"), 3, f"{field}.size"), mass, **common)
    if kind == "cylinder":
        orientation = spec.get("orientation", "lying")
        if orientation not in CYLINDER_ORIENTATIONS:
            raise InvalidInput(
                f"unknown cylinder orientation {orientation!r}",
                field=f"{field}.orientation",
                value=orientation,
                choices=CYLINDER_ORIENTATIONS,
            )
        r = check_positive(need("radius"), f"{field}.radius")
        length = check_positive(need("length"), f"{field}.length")
        return cylinder(r, length, mass, standing=orientation == "standing", **common)
    if kind == "sphere":
        return sphere(check_positive(need("radius"), f"{field}.radius"), mass, **common)
    if kind == "ellipsoid":
        return ellipsoid(check_positive_list(need("radii"), 3, f"{field}.radii"), mass, **common)
    V_raw, F_raw = need("vertices"), need("faces")
    try:
        V = np.asarray(V_raw, dtype=np.float64)
        F = np.asarray(F_raw)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("vertices/faces must be rectangular arrays", field=f"{field}.vertices") from exc
    check_mesh(V, F, field)
    return mesh(V, F, mass, **common)
