"""Principal directions of a point or displacement set, and the sign rule for axes.

Pure numpy, no I/O. Vectors are expressed in whatever frame the caller's points are in (for the closure
signature: the hand frame, docs/design.md §3); lengths are in the caller's unit (for the closure signature [m]).

``principal_components`` diagonalises the second-moment matrix of ``K`` samples, either about the origin
(``about="zero"``: the dominant direction of *motion* when the samples are displacements) or about their
mean (``about="mean"``: the classic covariance PCA). Moments are normalised by ``K`` (not ``K - 1``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput

AXIS_TIE_RTOL = 1e-6
"""Components whose magnitudes are within this fraction of the largest one tie for the sign in
:func:`orient_axes` (the first of them decides) [dimensionless]; far above round-off, so that a rotation by
1e-7 rad cannot flip an axis that lies on a tie."""

MomentOrigin = Literal["zero", "mean"]
MOMENT_ORIGINS: tuple[MomentOrigin, ...] = ("zero", "mean")


def orient_axes(vectors: ArrayLike, *, tie_rtol: float = AXIS_TIE_RTOL) -> NDArray[np.float64]:
    """Flip each vector (a row of ``vectors``, shape (..., d)) so that its sign is canonical.

    The rule (docs/design.md §4): the component of largest magnitude is made positive;
    where several components are within ``tie_rtol`` (relative) of the largest, the first of them decides.
    Unlike "the first non-zero component is positive", this does not flip under a tiny rotation of an axis
    that lies in a coordinate plane (every built-in hand's CS has x ~ 0): the sign changes only where two
    components are equal in magnitude, and a rotation smaller than ``tie_rtol`` rad cannot cross that
    boundary. A zero vector is returned unchanged. Returns a new array; lengths are preserved.
    """
    v = np.array(vectors, dtype=np.float64, copy=True)
    if v.ndim == 0:
        raise InvalidInput("vectors must have at least one dimension", field="vectors", value=v.shape)
    mag = np.abs(v)
    largest = np.max(mag, axis=-1, keepdims=True)
    candidates = (mag >= largest * (1.0 - tie_rtol)) & (largest > 0.0)
    first = np.argmax(candidates, axis=-1)
    pivot = np.take_along_axis(v, first[..., None], axis=-1)[..., 0]
    v[pivot < 0.0] *= -1.0
    return v + 0.0  # turns the -0.0 left by a flip into 0.0


@dataclass(frozen=True, eq=False)
class PrincipalComponents:
    """Principal directions of a sample set.

    ``directions[:, k]`` (columns) is the k-th unit principal direction, ordered by ``variances`` descending
    and sign-fixed with :func:`orient_axes`. ``variances[k]`` [unit^2] is the second moment along it (about
    ``origin``), ``explained_variance_ratio[k]`` = variances[k] / sum(variances) (all zeros when every sample
    sits at ``origin``), ``origin`` (d,) [unit] is the point the moments are taken about (zeros for
    ``about="zero"``, the sample mean for ``about="mean"``), ``n_samples`` = K.
    """

    directions: NDArray[np.float64]
    variances: NDArray[np.float64]
    explained_variance_ratio: NDArray[np.float64]
    origin: NDArray[np.float64]
    about: MomentOrigin
    n_samples: int

    @property
    def rms(self) -> NDArray[np.float64]:
        """Root-mean-square extent of the samples along each principal direction [unit]: sqrt(variances)."""
        return np.sqrt(self.variances)


def principal_components(points: ArrayLike, *, about: MomentOrigin = "mean") -> PrincipalComponents:
    """Principal directions of ``points`` (K, d) [unit], second moment about ``about`` ("zero" or "mean").

    Raises :class:`InvalidInput` for a wrong shape, K = 0, non-finite values or an unknown ``about``.
    """
    if about not in MOMENT_ORIGINS:
        raise InvalidInput("unknown moment origin", field="about", value=about, choices=MOMENT_ORIGINS)
    try:
        x = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("points must be a (K, d) array of numbers", field="points") from exc
    if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] < 1:
        raise InvalidInput("points must have shape (K, d) with K >= 1", field="points", value=list(x.shape))
    if not np.all(np.isfinite(x)):
        raise InvalidInput("points must be finite (no NaN or infinity)", field="points")
    k, d = x.shape
    origin = x.mean(axis=0) if about == "mean" else np.zeros(d)
    y = x - origin
    moment = (y.T @ y) / k
    eigval, eigvec = np.linalg.eigh(moment)
    order = np.argsort(-eigval, kind="stable")
    variances = np.clip(eigval[order], 0.0, None)
    directions = orient_axes(eigvec[:, order].T).T
    total = float(variances.sum())
    ratio = variances / total if total > 0.0 else np.zeros(d)
    return PrincipalComponents(
        directions=directions,
        variances=variances,
        explained_variance_ratio=ratio,
        origin=origin,
        about=about,
        n_samples=k,
    )
