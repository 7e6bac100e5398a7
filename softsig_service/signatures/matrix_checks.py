"""Small linear-algebra helpers of the stiffness math: checked matrices and vectors, symmetric parts, positive
semidefinite clipping and pseudo-inverses, plain-float lists for JSON.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput

PINV_RTOL = 1e-12
"""Relative eigenvalue cut-off of the symmetric pseudo-inverses and null-space bases."""


FloatArray = NDArray[np.float64]


def psd_pinv(M: ArrayLike, *, rtol: float = PINV_RTOL) -> FloatArray:
    """Pseudo-inverse of a symmetric positive semidefinite matrix by eigen-decomposition (relative cut-off)."""
    A = sym(np.asarray(M, dtype=np.float64))
    if A.size == 0:
        return A.copy()
    w, V = np.linalg.eigh(A)
    cut = rtol * max(float(np.max(np.abs(w))), 1e-300)
    inv = np.where(w > cut, 1.0 / np.where(w > cut, w, 1.0), 0.0)
    return sym((V * inv) @ V.T)


def is_psd(M: ArrayLike, *, rtol: float = 1e-9) -> bool:
    """Whether ``M`` is symmetric (to ``rtol`` of its largest entry) and has no eigenvalue below
    ``-rtol * max |eigenvalue|``."""
    A = np.asarray(M, dtype=np.float64)
    scale = max(float(np.max(np.abs(A))) if A.size else 0.0, 1e-300)
    if not np.allclose(A, A.T, atol=rtol * scale, rtol=0.0):
        return False
    w = np.linalg.eigvalsh(sym(A))
    return bool(w.min() >= -rtol * max(float(np.max(np.abs(w))), 1e-300))


def psd_clip(M: FloatArray, tol: float) -> FloatArray:
    """``M`` (symmetric) with its eigenvalues below ``tol`` set to 0."""
    if M.size == 0:
        return M
    w, V = np.linalg.eigh(sym(M))
    w = np.where(w < tol, 0.0, w)
    return sym((V * w) @ V.T)


def sym(M: FloatArray) -> FloatArray:
    return 0.5 * (M + M.T)


def rows_array(rows: Sequence[FloatArray], n: int) -> FloatArray:
    return np.array(rows, dtype=np.float64).reshape(-1, n)


def split_infinite(M: FloatArray, name: str) -> tuple[FloatArray, list[int]]:
    """Replace +inf diagonal entries by 0 and return their indices; reject NaN, -inf and off-diagonal inf."""
    if np.any(np.isnan(M)):
        raise InvalidInput("NaN in a stiffness matrix", field=name)
    inf = ~np.isfinite(M)
    if not inf.any():
        return M, []
    off = inf & ~np.eye(M.shape[0], dtype=bool)
    if off.any() or np.any(np.diag(M)[np.diag(inf)] < 0):
        raise InvalidInput("only +inf diagonal entries are allowed (a rigid joint or synergy)", field=name)
    idx = [int(i) for i in np.flatnonzero(np.diag(inf))]
    out = M.copy()
    out[idx, :] = 0.0
    out[:, idx] = 0.0
    return out, idx


def square_matrix(M: ArrayLike | None, name: str) -> FloatArray:
    if M is None:
        raise InvalidInput("missing matrix", field=name)
    try:
        A = np.asarray(M, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("expected numbers", field=name) from exc
    if A.ndim == 0:
        A = A.reshape(1, 1)
    elif A.ndim == 1:
        A = np.diag(A)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise InvalidInput("expected a square matrix or a diagonal vector", field=name, value=list(A.shape))
    if np.any(np.isnan(A)):
        raise InvalidInput("NaN in a matrix", field=name)
    finite = np.isfinite(A)
    if np.any(np.diag(A)[np.diag(finite)] < 0.0):
        raise InvalidInput("negative stiffness on the diagonal", field=name)
    A_f = np.where(finite, A, 0.0)
    if not np.allclose(A_f, A_f.T, atol=1e-9 * max(float(np.max(np.abs(A_f))), 1e-300), rtol=0.0):
        raise InvalidInput("a stiffness matrix must be symmetric", field=name)
    return A


def checked_matrix(M: ArrayLike, name: str, *, cols: int | None = None) -> FloatArray:
    try:
        A = np.asarray(M, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("expected numbers", field=name) from exc
    if cols is not None and A.ndim == 1 and A.size == cols:
        A = A.reshape(1, cols)
    if A.ndim != 2 or (cols is not None and A.shape[1] != cols):
        want = f"(n, {cols})" if cols is not None else "a 2-D array"
        raise InvalidInput(f"expected {want}", field=name, value=list(A.shape))
    if not np.all(np.isfinite(A)):
        raise InvalidInput("NaN or infinite values", field=name)
    return A


def checked_vector(v: ArrayLike, name: str, n: int) -> FloatArray:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.size != n or not np.all(np.isfinite(a)):
        raise InvalidInput(f"expected {n} finite numbers", field=name, value=a.tolist())
    return a


def checked_positive(x: float, name: str) -> float:
    try:
        f = float(x)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("expected a number", field=name, value=x) from exc
    if not math.isfinite(f) or f <= 0.0:
        raise InvalidInput("must be a finite number > 0", field=name, value=x)
    return f


def float_list(values: ArrayLike) -> list[float]:
    """``values`` flattened to a list of Python floats (JSON)."""
    return [float(x) for x in np.asarray(values, dtype=np.float64).reshape(-1)]


def json_fields(record: Any) -> dict[str, Any]:
    """The fields of dataclass instance ``record`` as JSON values: arrays as (nested) lists of floats, NumPy scalars
    as Python numbers and booleans, everything else as it is."""

    def value(v: Any) -> Any:
        if isinstance(v, np.ndarray):
            return np.asarray(v, dtype=np.float64).tolist()
        return v.item() if isinstance(v, np.generic) else v

    return {f.name: value(getattr(record, f.name)) for f in dataclasses.fields(record)}
