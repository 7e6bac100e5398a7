"""Plain JSON of computed results: NumPy scalars and arrays made lists and numbers, non-finite floats made null."""

from __future__ import annotations

import math
from typing import Any


def to_jsonable(value: Any) -> Any:
    """``value`` with NumPy scalars and arrays made plain and non-finite floats made ``None`` (valid JSON)."""
    t = type(value)  # the plain types first, by exact type (a plan's JSON is mostly these)
    if t is float:  # + 0.0 makes -0.0 plain 0.0 (a quaternion's "w": -0.0 is the same rotation, and reads oddly)
        return value + 0.0 if math.isfinite(value) else None
    if t is str or t is int or t is bool or value is None:
        return value
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_jsonable(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str | int):
        return value
    if isinstance(value, float):
        return float(value) + 0.0 if math.isfinite(value) else None
    tolist = getattr(value, "tolist", None)  # NumPy arrays and scalars
    if callable(tolist):
        return to_jsonable(tolist())
    return str(value)


VECTOR_KEYS = frozenset({"axis", "anchor", "center", "direction", "position", "normal", "force", "origin"})
"""Keys whose value, when a list of three numbers, is a 3-D vector (an axis, a point [m], a force [N])."""
VECTOR_ROW_KEYS = frozenset({"axes", "directions"})
"""Keys whose value, when a list of lists of three numbers, is a list of 3-D unit vectors."""


def _is_triple(value: Any) -> bool:
    return isinstance(value, list) and len(value) == 3 and all(isinstance(v, int | float) for v in value)


FRAME_KEYS = frozenset({"x", "y", "z"})
"""In a frame (a dict that also holds ``origin``), the keys of its unit axes."""


def vector_json(v: Any) -> dict[str, float]:
    """A 3-D vector (any sequence of three numbers) as ``{"x", "y", "z"}``, the REST API's form of a vector."""
    x, y, z = (float(c) for c in v)
    return {"x": x, "y": y, "z": z}


def vectors_as_objects(value: Any) -> Any:
    """``value`` (plain JSON) with every 3-D vector under :data:`VECTOR_KEYS` (and every row of a list under
    :data:`VECTOR_ROW_KEYS`, and the axes of a frame, :data:`FRAME_KEYS` beside an ``origin``) written as
    ``{"x", "y", "z"}``, the REST API's one form of a vector, and CLI's ``--json``. Lists that are not triples
    (joint positions, per-axis values, matrices) are left as they are."""
    t = type(value)  # plain scalars first, by exact type (most of a plan's JSON)
    if t is float or t is int or t is str or t is bool or value is None:
        return value
    if isinstance(value, dict):
        out: dict[str, Any] = {}
        frame = "origin" in value
        for k, v in value.items():
            if (k in VECTOR_KEYS or (frame and k in FRAME_KEYS)) and _is_triple(v):
                out[k] = {"x": v[0], "y": v[1], "z": v[2]}
            elif k in VECTOR_ROW_KEYS and isinstance(v, list) and v and all(_is_triple(r) for r in v):
                out[k] = [{"x": r[0], "y": r[1], "z": r[2]} for r in v]
            else:
                out[k] = vectors_as_objects(v)
        return out
    if isinstance(value, list):
        return [vectors_as_objects(v) for v in value]
    return value


def api_json(value: Any) -> Any:
    """``vectors_as_objects(to_jsonable(value))`` in one pass over ``value`` (a plan's JSON on every request)."""
    t = type(value)
    if t is float:
        return value + 0.0 if math.isfinite(value) else None
    if t is str or t is int or t is bool or value is None:
        return value
    if isinstance(value, dict):
        out: dict[str, Any] = {}
        items = [(k if type(k) is str else str(k), v) for k, v in value.items()]
        frame = any(k == "origin" for k, _ in items)
        for k, v in items:
            j = api_json(v)
            if (k in VECTOR_KEYS or (frame and k in FRAME_KEYS)) and _is_triple(j):
                out[k] = {"x": j[0], "y": j[1], "z": j[2]}
            elif k in VECTOR_ROW_KEYS and isinstance(j, list) and j and all(_is_triple(r) for r in j):
                out[k] = [{"x": r[0], "y": r[1], "z": r[2]} for r in j]
            else:
                out[k] = j
        return out
    if isinstance(value, list | tuple):
        return [api_json(v) for v in value]
    return vectors_as_objects(to_jsonable(value))
