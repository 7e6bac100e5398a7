"""Validation of geometric inputs: finite arrays of a given shape, naming the offending field in the error."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput

FloatArray = NDArray[np.float64]

ORTHONORMAL_TOL = 1e-6
"""How far a rotation matrix may be from orthonormal with determinant 1."""


def as_finite_array(value: ArrayLike, shape: tuple[int, ...], field: str) -> FloatArray:
    """Return ``value`` as a float64 array of ``shape``, or raise :class:`InvalidInput` naming ``field``.

    Rejects wrong shapes, non-numeric entries, NaN and infinite values.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("expected numbers", field=field, value=_short(value)) from exc
    if arr.shape != shape:
        raise InvalidInput(f"expected shape {shape}, got {arr.shape}", field=field, value=_short(value))
    if not np.all(np.isfinite(arr)):
        raise InvalidInput("contains NaN or infinite values", field=field, value=_short(value))
    return arr


def _short(value: Any) -> Any:
    """A compact representation of a bad value for an error message."""
    if isinstance(value, np.ndarray):
        return value.tolist() if value.size <= 16 else f"array of shape {value.shape}"
    return value


def check_rotation(R: ArrayLike, field: str = "rotation") -> FloatArray:
    """Return ``R`` as a 3x3 array if it is a proper rotation (orthonormal, det +1, within 1e-6)."""
    M = as_finite_array(R, (3, 3), field)
    if not np.allclose(M.T @ M, np.eye(3), atol=ORTHONORMAL_TOL) or abs(np.linalg.det(M) - 1.0) > ORTHONORMAL_TOL:
        raise InvalidInput("not a proper rotation matrix (orthonormal, det +1)", field=field, value=M.tolist())
    return M


def wire_number(d: Mapping[str, Any], key: str, field: str) -> float:
    """One finite number ``d[key]`` from a wire mapping, with ``field.key`` in errors."""
    if not isinstance(d, Mapping):
        raise InvalidInput("expected an object with named fields", field=field, value=_short(d))
    if key not in d:
        raise InvalidInput(f"missing key {key!r}", field=f"{field}.{key}")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
        raise InvalidInput("expected a number", field=f"{field}.{key}", value=v)
    f = float(v)
    if not math.isfinite(f):
        raise InvalidInput("NaN or infinite value", field=f"{field}.{key}", value=v)
    return f
