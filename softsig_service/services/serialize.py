"""Plain JSON of computed results: NumPy scalars and arrays made lists and numbers, non-finite floats made null."""

from __future__ import annotations

import math
from typing import Any


def to_jsonable(value: Any) -> Any:
    """``value`` with NumPy scalars and arrays made plain and non-finite floats made ``None`` (valid JSON)."""
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_jsonable(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str | int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    tolist = getattr(value, "tolist", None)  # NumPy arrays and scalars
    if callable(tolist):
        return to_jsonable(tolist())
    return str(value)
