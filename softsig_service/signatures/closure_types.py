"""The result types of the closure signature: :class:`ClosureSignature` and :class:`EllipsoidAxisSeries`, every vector
in the hand frame (docs/design.md §3, §4); lengths [m].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from softsig_service.geometry.ellipsoid import (
    Ellipsoid,
)
from softsig_service.signatures.matrix_checks import float_list

Method = Literal["ellipsoid", "pca", "mesh"]
METHODS: tuple[Method, ...] = ("ellipsoid", "pca", "mesh")
Criterion = Literal["absolute", "relative"]
"""How the ellipsoid method measures the change of a half-width: ``a_k(T) - a_k(0)`` [m] or that / ``a_k(0)``."""
CRITERIA: tuple[Criterion, ...] = ("absolute", "relative")
"""The ellipsoid criteria; the first, "absolute", is the default (docs/design.md §4)."""
DEFAULT_CRITERION: Criterion = "absolute"
MeshSource = Literal["surface", "reference_points"]

DISTINCTNESS_CAP = 1e6
"""Reported distinctness when the second-largest |deformation| is 0 (or the ratio would exceed it)."""
AMBIGUITY_THRESHOLD = 1.1
"""A CS whose distinctness is below this is flagged ``ambiguous`` (docs/design.md §4)."""
ELLIPSOID_RESOLUTION_FACTOR = 10.0
"""Ellipsoid deltas with |delta| <= this x tol (relative criterion), or this x tol x the largest semi-axis of E_0
and E_T [m] (absolute criterion), are below the MVEE's precision and count as 0 in distinctness."""
PCA_RESOLUTION_RTOL = 1e-12
"""PCA RMS displacements <= this x max |coordinate| [m] are round-off and count as 0 in distinctness."""
MESH_RESOLUTION = 1e-9
"""Mesh ln-stretches with |ln lambda| <= this are round-off of the fit and count as 0 in distinctness."""
DEGENERATE_RTOL = 1e-9
"""Mesh method: smallest / largest singular value of the centred initial points must exceed this."""
NEARLY_EQUAL_RTOL = 1e-3
"""Two semi-axes of E_0 within this relative difference make their directions ill-defined (ellipsoid method)."""


@dataclass(frozen=True, eq=False)
class ClosureSignature:
    """The closure signature of one closure, by one method, in the hand frame.

    Attributes:
        method: "ellipsoid", "pca" or "mesh".
        params: the method's parameters (JSON-ready): ellipsoid ``{"tol", "max_iter", "lift_epsilon",
            "criterion"}``, pca ``{"about"}``, mesh ``{"source"}``.
        axis: (3,) unit CS axis in the hand frame, sign rule of docs/design.md §4 (== ``axes[0]``).
        anchor: (3,) point the axis passes through [m], hand frame (c_0 or the initial centroid).
        magnitude: ``deformation[0]``: ellipsoid delta, signed: with ``params["criterion"] == "absolute"`` (the
            default) the change of the half-width [m], with "relative" that change / the initial half-width
            (dimensionless); pca RMS displacement [m] (>= 0); mesh ln-stretch (dimensionless, signed).
        deformation: (3,) the per-axis values, same unit as ``magnitude``, aligned with the rows of ``axes``.
        axes: (3, 3) unit vectors as **rows**, ordered by |deformation| descending.
        distinctness: |deformation[0]| / |deformation[1]| (capped at :data:`DISTINCTNESS_CAP`).
        initial_ellipsoid, final_ellipsoid: E_0 and E_T (ellipsoid method only, else None).
        extras: method-specific, JSON-ready diagnostics (see :meth:`to_json_dict`).
        frame_id: always "hand".
    """

    method: Method
    params: dict[str, Any]
    axis: NDArray[np.float64]
    anchor: NDArray[np.float64]
    magnitude: float
    deformation: NDArray[np.float64]
    axes: NDArray[np.float64]
    distinctness: float
    initial_ellipsoid: Ellipsoid | None = None
    final_ellipsoid: Ellipsoid | None = None
    extras: dict[str, Any] = field(default_factory=dict)
    frame_id: str = "hand"

    @property
    def ambiguous(self) -> bool:
        """True when the CS is not distinct: ``distinctness < 1.1``."""
        return self.distinctness < AMBIGUITY_THRESHOLD

    def to_json_dict(self) -> dict[str, Any]:
        """JSON form: method, frame_id, axis, anchor [m], magnitude, deformation, axes (3 unit vectors),
        distinctness, ambiguous, params, extras, and for the ellipsoid method initial_ellipsoid and
        final_ellipsoid, each ``{center [m], semi_axes [m], axes (3 unit vectors)}``.

        ``extras`` always has ``magnitude_unit`` ("1" or "m"), ``resolution`` (same unit), ``n_frames`` and
        ``n_points``, plus ellipsoid (``magnitude_unit`` "m" for the absolute criterion, "1" for the relative):
        ``absolute_change`` [m], ``relative_change`` (dimensionless), ``centre_drift`` [m],
        ``half_width_initial`` [m], ``half_width_final`` [m] (all per row of axes, whichever the criterion),
        ``lifted_epsilon`` {initial, final} [m], ``solver`` {initial, final: {iterations, converged, gap}};
        pca: ``explained_variance_ratio`` (per row of axes), ``rms_displacement`` [m], ``n_displacements``;
        mesh: ``stretches`` and ``signed_stretches`` (per row of axes; one negative when ``det_F`` < 0, flagged in
        ``warnings``), ``fit_residual_rms`` [m], ``fit_residual_max`` [m], ``det_F``, ``rotation_angle`` [rad] (of
        the proper rotation), ``affine_matrix`` (3 rows), ``affine_offset`` [m].
        """
        out: dict[str, Any] = {
            "method": self.method,
            "frame_id": self.frame_id,
            "axis": float_list(self.axis),
            "anchor": float_list(self.anchor),
            "magnitude": float(self.magnitude),
            "deformation": float_list(self.deformation),
            "axes": [float_list(row) for row in self.axes],
            "distinctness": float(self.distinctness),
            "ambiguous": self.ambiguous,
            "params": dict(self.params),
        }
        if self.initial_ellipsoid is not None and self.final_ellipsoid is not None:
            out["initial_ellipsoid"] = self.initial_ellipsoid.to_json_dict()
            out["final_ellipsoid"] = self.final_ellipsoid.to_json_dict()
        out["extras"] = dict(self.extras)
        return out


@dataclass(frozen=True, eq=False)
class EllipsoidAxisSeries:
    """Per-frame half-widths of E_t along the initial axes r_k (the ellipsoid method's step 4).

    Attributes:
        axes: (3, 3) the r_k as rows (sign rule applied), ordered by E_0's semi-axes descending.
        half_widths: (T, 3) a_k(t) = sqrt(r_k^T A_t^-1 r_k) [m].
        absolute_change: (T, 3) a_k(t) - a_k(0) [m]; the last row is delta_k of the absolute criterion.
        relative_change: (T, 3) a_k(t) / a_k(0) - 1 (dimensionless); the last row is delta_k of the relative
            criterion.
        centre_drift: (T, 3) r_k^T (c_t - c_0) [m].
        iterations, converged, lifted_epsilon [m]: (T,) solver diagnostics of each E_t.
    """

    axes: NDArray[np.float64]
    half_widths: NDArray[np.float64]
    absolute_change: NDArray[np.float64]
    relative_change: NDArray[np.float64]
    centre_drift: NDArray[np.float64]
    iterations: NDArray[np.int64]
    converged: NDArray[np.bool_]
    lifted_epsilon: NDArray[np.float64]
