"""Objects resting on the table: shape model, constructors, the built-in catalogue and JSON parsing.

Frames, units and the JSON schema: :mod:`softsig_service.objects.shape`.
"""

from softsig_service.objects.checks import check_mesh, check_number, check_positive, check_positive_list
from softsig_service.objects.constructors import box, cylinder, ellipsoid, mesh, sphere
from softsig_service.objects.footprint import convex_hull_2d, polygon_moments
from softsig_service.objects.parse import builtin_object, object_from_json
from softsig_service.objects.shape import (
    BUILTIN_NAMES,
    CYLINDER_ORIENTATIONS,
    DEFAULT_FRICTION,
    DEFAULT_X,
    DEFAULT_Y,
    HOUSEHOLD_NAMES,
    OBJECT_KINDS,
    OBJECT_NAMES,
    ObjectKind,
    ShapePrimitive,
    TableObject,
)

__all__ = [
    "BUILTIN_NAMES",
    "CYLINDER_ORIENTATIONS",
    "DEFAULT_FRICTION",
    "DEFAULT_X",
    "DEFAULT_Y",
    "HOUSEHOLD_NAMES",
    "OBJECT_KINDS",
    "OBJECT_NAMES",
    "ObjectKind",
    "ShapePrimitive",
    "TableObject",
    "box",
    "builtin_object",
    "check_mesh",
    "check_number",
    "check_positive",
    "check_positive_list",
    "convex_hull_2d",
    "cylinder",
    "ellipsoid",
    "mesh",
    "object_from_json",
    "polygon_moments",
    "sphere",
]
