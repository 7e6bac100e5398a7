"""Validation of object inputs: numbers, positive numbers and lists, triangle meshes.

Each check raises :class:`~softsig_service.errors.InvalidInput` naming the offending field (``object.size[2]``).
Lengths in [m]; pure numpy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def check_number(v: Any, field: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
        raise InvalidInput("expected a number", field=field, value=v)
    f = float(v)
    if not math.isfinite(f):
        raise InvalidInput("NaN or infinite value", field=field, value=v)
    return f


MAX_ANGLE = 2.0 * math.pi
"""[rad] the largest angle taken: a turn either way (a larger one is most likely in degrees by mistake)."""


def check_angle(v: float, field: str) -> float:
    """``v`` [rad] within [-2 pi, 2 pi], else :class:`InvalidInput` naming ``field``."""
    if not -MAX_ANGLE <= v <= MAX_ANGLE:
        raise InvalidInput(
            f"an angle in radians within [-2 pi, 2 pi] (is {v:g} in degrees? that is {math.radians(v):.4g} rad)",
            field=field,
            value=v,
        )
    return v


def check_positive(v: Any, field: str) -> float:
    f = check_number(v, field)
    if f <= 0.0:
        raise InvalidInput("must be > 0", field=field, value=v)
    return f


def check_positive_list(v: Any, n: int, field: str) -> tuple[float, ...]:
    if isinstance(v, str | bytes | Mapping) or not isinstance(v, Sequence | np.ndarray):
        raise InvalidInput(f"expected a list of {n} numbers", field=field, value=v)
    if len(v) != n:
        raise InvalidInput(f"expected {n} values, got {len(v)}", field=field, value=list(v))
    return tuple(check_positive(x, f"{field}[{i}]") for i, x in enumerate(v))


def check_mesh(vertices: ArrayLike, faces: ArrayLike, field: str) -> tuple[FloatArray, IntArray]:
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
    repeated = np.flatnonzero((F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2]))
    if repeated.size:
        k = int(repeated[0])
        raise InvalidInput("a face must name three different vertices", field=f"{field}.faces[{k}]",
                           value=[int(i) for i in F[k]])  # fmt: skip
    centred = V - V.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[-1] <= 1e-9 * max(float(sv[0]), 1e-12):
        raise InvalidInput("the mesh is flat or degenerate (no volume)", field=f"{field}.vertices")
    return V, F
