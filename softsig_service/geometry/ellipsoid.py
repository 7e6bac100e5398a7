"""Minimum-volume enclosing ellipsoid (MVEE) of a point set, by Khachiyan's algorithm.

Pure numpy, no I/O. Points are in the caller's frame and unit (for the closure signature: the hand frame [m]).
An ellipsoid is ``E = {x : (x - c)^T A (x - c) <= 1}`` with centre ``c`` [m] and shape matrix ``A`` [1/m^2]
(symmetric positive definite); its semi-axes are ``a_k = 1 / sqrt(eig_k(A))`` [m] along the eigenvectors of A.

The MVEE is found from its dual by Khachiyan's algorithm with Newton steps
(:mod:`softsig_service.geometry.khachiyan`), on points centred, scaled and whitened first (an affine map, under
which the MVEE is equivariant), so the problem is well conditioned however thin or far from the origin the
cloud is; the result is mapped back.

Every input point lies in E (up to round-off), also when ``max_iter`` ends the iteration first; ``converged``
and ``gap`` then say how far from optimal E is.

Coplanar / collinear points (the fallback)
-------------------------------------------
Let ``s_1 >= ... >= s_d`` be the root-mean-square extents of the centred points along their principal
directions [m]. A direction with ``s_k < lift_epsilon * s_1`` is *missing* (the points are, to that relative
precision, coplanar or collinear and have no finite-volume MVEE). The cloud is then lifted: every point ``p``
is replaced by the pairs ``p + h v_k`` and ``p - h v_k`` for each missing unit direction ``v_k``, with
``h = lift_epsilon * s_1`` [m]. The original points are midpoints of lifted ones, so they stay inside E, and E
has a semi-axis of order ``h`` along each missing direction. ``h`` is reported as ``lifted_epsilon`` [m] (0.0
when nothing was lifted) and the number of missing directions as ``n_lifted``. The lifted set is a product, so
in the plane (on the line) E keeps the centre and axes of the plane's minimum ellipse (of the segment), scaled
by exactly sqrt(3/2) (sqrt(3) for a line): a property of the MVEE of a flat 3-D set, not an error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypedDict

import numpy as np
from numpy.typing import ArrayLike, NDArray
from typing_extensions import Unpack

from softsig_service.errors import InvalidInput
from softsig_service.geometry.khachiyan import mvee_normalised
from softsig_service.geometry.pca import orient_axes

DEFAULT_TOL = 1e-7
"""Default Todd–Yildirim tolerance of the optimality conditions (relative, dimensionless)."""
MAX_TOL = 1e-7
"""Loosest accepted tolerance (docs/design.md §4: <= 1e-7)."""
MIN_TOL = 1e-13
"""Tightest accepted tolerance: below this, round-off can keep the conditions from ever being met."""
DEFAULT_MAX_ITER = 500
"""Default iteration cap (6 points in 3-D need about 5-10 iterations; lifted sets of 24 points about 30)."""
DEFAULT_LIFT_EPSILON = 1e-6
"""Default relative lift for coplanar/collinear points (fraction of the cloud's largest RMS extent)."""
MIN_LIFT_EPSILON = 1e-9
MAX_LIFT_EPSILON = 1e-2
COINCIDENT_RTOL = 1e-12
"""Points whose spread is below this fraction of their coordinates' magnitude are one point (no ellipsoid)."""


@dataclass(frozen=True, eq=False)
class Ellipsoid:
    """``E = {x : (x - center)^T shape (x - center) <= 1}`` with its Khachiyan diagnostics.

    Attributes:
        center: (d,) centre c [m].
        shape: (d, d) symmetric positive-definite matrix A [1/m^2].
        semi_axes: (d,) semi-axis lengths a_k = 1 / sqrt(eig_k(A)) [m], descending.
        axes: (d, d) unit eigenvectors of A as *columns*: ``axes[:, k]`` carries ``semi_axes[k]``; each
            column's sign follows :func:`~softsig_service.geometry.pca.orient_axes`.
        iterations: Khachiyan/Newton iterations taken.
        converged: whether the optimality conditions were met to ``tol`` within ``max_iter``.
        gap: the achieved Todd–Yildirim measure (dimensionless; <= tol when converged).
        lifted_epsilon: lift h [m] applied along missing directions (0.0 if the points span d dimensions).
        n_lifted: number of missing directions that were lifted (0 for a full-dimensional cloud).
    """

    center: NDArray[np.float64]
    shape: NDArray[np.float64]
    semi_axes: NDArray[np.float64]
    axes: NDArray[np.float64]
    iterations: int
    converged: bool
    gap: float
    lifted_epsilon: float
    n_lifted: int

    @property
    def dim(self) -> int:
        """Dimension d of the space."""
        return int(self.center.shape[0])

    @property
    def volume(self) -> float:
        """Volume [m^d]: that of the unit d-ball times the product of the semi-axes."""
        d = self.dim
        unit_ball = math.pi ** (d / 2) / math.gamma(d / 2 + 1)
        return float(unit_ball * np.prod(self.semi_axes))

    def inverse_shape(self) -> NDArray[np.float64]:
        """A^-1 [m^2], built from the eigen-decomposition (better conditioned than inverting A)."""
        r = self.axes
        return np.asarray((r * self.semi_axes**2) @ r.T, dtype=np.float64)

    def half_width(self, direction: ArrayLike) -> float:
        """Half-width of E along ``direction`` (normalised here) [m]: support function sqrt(r^T A^-1 r)."""
        r = np.asarray(direction, dtype=np.float64)
        norm = float(np.linalg.norm(r))
        if r.shape != self.center.shape or not math.isfinite(norm) or norm == 0.0:
            raise InvalidInput("direction must be a finite non-zero (d,) vector", field="direction")
        r = r / norm
        return float(np.sqrt(r @ self.inverse_shape() @ r))

    def level(self, points: ArrayLike) -> NDArray[np.float64]:
        """``(x - c)^T A (x - c)`` for each row x of ``points`` (K, d) (dimensionless; <= 1 inside E).

        Evaluated as ``sum_k ((x - c) . axes[:, k] / semi_axes[k])^2``, which keeps its relative precision for
        thin ellipsoids (the quadratic form in A loses round-off times cond(A)).
        """
        x = np.asarray(points, dtype=np.float64) - self.center
        return np.asarray(np.sum((x @ self.axes / self.semi_axes) ** 2, axis=-1), dtype=np.float64)

    def contains(self, points: ArrayLike, *, rtol: float = 1e-9) -> NDArray[np.bool_]:
        """Whether each row of ``points`` (K, d) lies in E, with relative slack ``rtol`` on the level."""
        return np.asarray(self.level(points) <= 1.0 + rtol)

    def to_json_dict(self) -> dict[str, list[float] | list[list[float]]]:
        """``{center [m], semi_axes [m], axes}``, axes as the list of d unit vectors (columns of ``axes``)."""
        return {
            "center": [float(v) for v in self.center],
            "semi_axes": [float(v) for v in self.semi_axes],
            "axes": [[float(v) for v in col] for col in self.axes.T],
        }


@dataclass(frozen=True, eq=False)
class EllipsoidBatch:
    """MVEEs of B point sets, stacked (same fields as :class:`Ellipsoid` with a leading batch axis)."""

    center: NDArray[np.float64]
    shape: NDArray[np.float64]
    semi_axes: NDArray[np.float64]
    axes: NDArray[np.float64]
    iterations: NDArray[np.int64]
    converged: NDArray[np.bool_]
    gap: NDArray[np.float64]
    lifted_epsilon: NDArray[np.float64]
    n_lifted: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.center.shape[0])

    def __getitem__(self, index: int) -> Ellipsoid:
        return Ellipsoid(
            center=self.center[index],
            shape=self.shape[index],
            semi_axes=self.semi_axes[index],
            axes=self.axes[index],
            iterations=int(self.iterations[index]),
            converged=bool(self.converged[index]),
            gap=float(self.gap[index]),
            lifted_epsilon=float(self.lifted_epsilon[index]),
            n_lifted=int(self.n_lifted[index]),
        )


class MveeOptions(TypedDict, total=False):
    """Options of the MVEE fit (:func:`mvee`, :func:`mvee_batch` and the ellipsoid closure signature); every one
    may be left out: ``tol`` (:data:`DEFAULT_TOL`), ``max_iter`` (:data:`DEFAULT_MAX_ITER`), ``lift_epsilon``
    (:data:`DEFAULT_LIFT_EPSILON`)."""

    tol: float
    max_iter: int
    lift_epsilon: float


def mvee_params(options: MveeOptions) -> MveeOptions:
    """``options`` with every option present (the defaults filled in), e.g. to record them beside a result."""
    return {
        "tol": options.get("tol", DEFAULT_TOL),
        "max_iter": options.get("max_iter", DEFAULT_MAX_ITER),
        "lift_epsilon": options.get("lift_epsilon", DEFAULT_LIFT_EPSILON),
    }


def mvee(points: ArrayLike, **options: Unpack[MveeOptions]) -> Ellipsoid:
    """Minimum-volume ellipsoid enclosing the rows of ``points`` (N, d) [m], N >= d + 1.

    See the module docstring for the algorithm, ``tol`` (in [1e-13, 1e-7], default 1e-7), ``max_iter`` and the
    coplanar fallback ``lift_epsilon`` (relative, in [1e-9, 1e-2], default 1e-6). Raises :class:`InvalidInput`
    for a wrong shape, too few points, non-finite values, coincident points or out-of-range parameters.
    """
    arr = _as_float_array(points)
    if arr.ndim != 2:
        raise InvalidInput("points must have shape (N, d)", field="points", value=list(arr.shape))
    return mvee_batch(arr[None], **options)[0]


def mvee_batch(points: ArrayLike, **options: Unpack[MveeOptions]) -> EllipsoidBatch:
    """MVEE of each of B point sets ``points`` (B, N, d) [m], vectorised over the batch (see :func:`mvee`)."""
    full = mvee_params(options)
    tol, max_iter, lift_epsilon = full["tol"], full["max_iter"], full["lift_epsilon"]
    x = _as_float_array(points)
    _check_params(x, tol, max_iter, lift_epsilon)
    b, n, d = x.shape

    # Centre and scale each frame (normalised coordinates y, O(1)); detect coincident and flat clouds.
    mean = x.mean(axis=1)
    xc = x - mean[:, None, :]
    scale = np.abs(xc).max(axis=(1, 2))
    magnitude = np.abs(x).max(axis=(1, 2))
    coincident = ~(scale > COINCIDENT_RTOL * magnitude)
    if np.any(coincident):
        frame = int(np.argmax(coincident))
        raise InvalidInput(
            "the points coincide: an ellipsoid needs points spanning at least a line",
            field="points" if b == 1 else f"points[{frame}]",
            value=float(scale[frame]),
        )
    y = xc / scale[:, None, None]
    eigval, eigvec = np.linalg.eigh(np.einsum("bni,bnj->bij", y, y) / n)
    rms = np.sqrt(np.clip(eigval, 0.0, None))  # ascending
    missing = rms < lift_epsilon * rms[:, -1:]
    n_missing = missing.sum(axis=1)
    h = lift_epsilon * rms[:, -1]  # lift distance in normalised units

    center_y = np.empty((b, d))
    cov_y = np.empty((b, d, d))
    shape_y = np.empty((b, d, d))
    iterations = np.zeros(b, dtype=np.int64)
    converged = np.zeros(b, dtype=bool)
    gap = np.zeros(b)
    for m in np.unique(n_missing):
        idx = np.flatnonzero(n_missing == m)
        pts = y[idx]
        if m > 0:
            # missing directions are the first m eigenvectors (smallest extents): lift +-h along each
            dirs = eigvec[idx][:, :, :m].transpose(0, 2, 1)  # (g, m, d)
            offsets = h[idx, None, None] * dirs
            pts = np.concatenate(
                [pts[:, None, :, :] + offsets[:, :, None, :], pts[:, None, :, :] - offsets[:, :, None, :]],
                axis=1,
            ).reshape(len(idx), 2 * int(m) * n, d)
        c_g, cov_g, shape_g, it_g, conv_g, gap_g = mvee_normalised(pts, tol, max_iter)
        center_y[idx] = c_g
        cov_y[idx] = cov_g
        shape_y[idx] = shape_g
        iterations[idx] = it_g
        converged[idx] = conv_g
        gap[idx] = gap_g

    # Back to the caller's coordinates, x = mean + scale * y. The axes are the eigenvectors of A^-1; each squared
    # semi-axis is taken from the operator in which it is a *large* eigenvalue: v^T A^-1 v for the long axes,
    # 1 / (v^T A v) for the short ones, so that a thin ellipsoid's short axes keep full relative precision
    # (eigenvalues are accurate to round-off times the largest one).
    var, vec = np.linalg.eigh(cov_y)  # ascending
    var, vec = var[:, ::-1], vec[:, :, ::-1]
    from_shape = 1.0 / np.einsum("bik,bij,bjk->bk", vec, shape_y, vec)
    short = var < np.sqrt(var[:, :1] * var[:, -1:])
    semi_axes = scale[:, None] * np.sqrt(np.where(short, from_shape, var))
    order = np.argsort(-semi_axes, axis=1, kind="stable")  # re-sort: near-ties may swap by round-off
    semi_axes = np.take_along_axis(semi_axes, order, axis=1)
    vec = np.take_along_axis(vec, order[:, None, :], axis=2)
    axes = orient_axes(vec.transpose(0, 2, 1)).transpose(0, 2, 1)
    shape = (axes / semi_axes[:, None, :] ** 2) @ axes.transpose(0, 2, 1)
    return EllipsoidBatch(
        center=mean + scale[:, None] * center_y,
        shape=shape,
        semi_axes=semi_axes,
        axes=axes,
        iterations=iterations,
        converged=converged,
        gap=gap,
        lifted_epsilon=np.where(n_missing > 0, h * scale, 0.0),
        n_lifted=n_missing.astype(np.int64),
    )


def _as_float_array(points: ArrayLike) -> NDArray[np.float64]:
    try:
        return np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("points must be an array of numbers", field="points") from exc


def _check_params(x: NDArray[np.float64], tol: float, max_iter: int, lift_epsilon: float) -> None:
    if x.ndim != 3 or x.shape[2] < 1:
        raise InvalidInput("points must have shape (B, N, d)", field="points", value=list(x.shape))
    b, n, d = x.shape
    if b < 1:
        raise InvalidInput("at least one point set is needed", field="points", value=list(x.shape))
    if n < d + 1:
        raise InvalidInput(f"an ellipsoid in {d}-D needs at least {d + 1} points", field="points", value=n)
    if not np.all(np.isfinite(x)):
        where = np.argwhere(~np.isfinite(x))[0]
        field = "points[" + "][".join(str(int(i)) for i in (where[1:] if b == 1 else where)) + "]"
        raise InvalidInput("points must be finite (no NaN or infinity)", field=field)
    if not (MIN_TOL <= tol <= MAX_TOL):
        raise InvalidInput(f"tol must be in [{MIN_TOL:g}, {MAX_TOL:g}]", field="tol", value=tol)
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 0:
        raise InvalidInput("max_iter must be a non-negative integer", field="max_iter", value=max_iter)
    if not (MIN_LIFT_EPSILON <= lift_epsilon <= MAX_LIFT_EPSILON):
        raise InvalidInput(
            f"lift_epsilon must be in [{MIN_LIFT_EPSILON:g}, {MAX_LIFT_EPSILON:g}]",
            field="lift_epsilon",
            value=lift_epsilon,
        )
