"""The closure signature (CS) of a hand: the axis along which the hand closes (docs/design.md §4).

Pure math, no I/O. Input positions are ``P[t, i, :]`` [m], reference point ``i`` at sample ``t`` in the *hand
frame* (origin at the flange, +z = approach, +x across the palm; docs/design.md §3), t = 0 the open hand, t = T-1 the
closed hand. Every vector of a :class:`ClosureSignature` is in the hand frame.

Three methods, one result type:

* **ellipsoid** (:func:`ellipsoid_closure_signature`) — the five steps of docs/design.md §4: E_0, E_T = minimum-volume
  enclosing ellipsoids of the first and last frames (:func:`~softsig_service.geometry.ellipsoid.mvee`); along
  each axis r_k of E_0 the half-width ``a_k(t) = sqrt(r_k^T A_t^-1 r_k)`` [m]; the change of each half-width
  is delta_k, by one of two criteria (:data:`CRITERIA`):

  - ``"absolute"`` (the default, docs/design.md §4): ``delta_k = a_k(T) - a_k(0)`` [m], negative = the hand narrows
    along r_k;
  - ``"relative"`` (an option, never the default): ``delta_k = (a_k(T) - a_k(0)) / a_k(0)`` (dimensionless).
    It is large along a thin axis of E_0 whatever the hand does: a nearly flat open hand tends to get its
    normal as the CS.

  An axis of E_0 that exists only because coplanar or collinear open points were lifted (``n_lifted`` of
  :class:`~softsig_service.geometry.ellipsoid.Ellipsoid`; its half-width is the lift, of order
  ``lift_epsilon``) is never elected: the CS is the real axis of the largest |delta_k|, the lifted axes are
  listed last and named in ``extras["lifted_axes"]`` (their deltas are still reported). When two semi-axes of
  E_0 are within :data:`NEARLY_EQUAL_RTOL` of each other, their directions are ill-defined (any rotation in
  their plane fits as well): ``extras["ill_defined_axes"]`` names the pairs (indices into ``axes``) and
  ``extras["warnings"]`` says so.

  The CS is the r_k with the largest |delta_k|, anchored at c_0, magnitude delta_k*. Both changes are reported
  whichever criterion elects the CS (``extras["absolute_change"]`` [m], ``extras["relative_change"]``), and so
  is the centre drift ``r_k^T (c_T - c_0)`` [m]. Only E_0 and E_T are fitted; :func:`ellipsoid_axis_series`
  gives a_k(t), both changes and the drift for every frame.
* **pca** (:func:`pca_closure_signature`) — displacements ``D = P[t] - P[0]`` for t = 1..T-1 (the identically
  zero t = 0 block is left out) and every point, stacked; principal directions of their second moment about
  zero (or, optionally, about their mean). deformation_k = RMS displacement along direction k [m] (square root
  of the second moment), magnitude = that of the first direction [m] (>= 0: a direction of motion, not a
  signed change); anchor = centroid of P[0]. Explained-variance ratios are reported.
* **mesh** (:func:`mesh_closure_signature`) — least-squares affine map ``x_T = F x_0 + b`` between the first
  and last frames of a dense set of hand-surface points (falling back to the reference points when the
  trajectory has no surface), polar decomposition ``F = R U`` (by SVD, F = W S V^T, U = V S V^T, R = W V^T);
  the CS is the eigenvector of U whose stretch lambda has the largest |ln lambda|. deformation_k = ln lambda_k
  (Hencky strain, dimensionless, negative = contraction) and magnitude = ln lambda_k*; anchor = centroid of
  the initial points. The stretches and the fit residual [m] are reported.

Conventions common to the three:

* ``axes`` is a (3, 3) array whose **rows** are unit vectors, ordered by |deformation| descending (ties keep
  the method's own order), so ``axes[0]`` is the CS ``axis``, ``deformation[0]`` its value and
  ``magnitude == deformation[0]``. The rows are not necessarily a right-handed triad.
* Sign rule (:func:`~softsig_service.geometry.pca.orient_axes`), applied to every row: the component of
  largest magnitude is positive (the first of near-equal ones decides).
* ``distinctness = |deformation[0]| / |deformation[1]|``; when the second is 0 (or the ratio exceeds it) it
  is :data:`DISTINCTNESS_CAP` (1e6); when all deformations are 0 it is 1.0. ``ambiguous`` means
  ``distinctness < 1.1``. "0" means at or below the method's numerical resolution, reported as
  ``extras["resolution"]``: for the ellipsoid deltas 10 x tol x the largest semi-axis of E_0 and E_T [m]
  (absolute criterion; the MVEE's rescaling enlarges each semi-axis by a relative ~tol, so a half-width is
  known to about tol x its length) or 10 x tol (relative criterion); 1e-12 x the largest |coordinate| [m] for
  pca; 1e-9 for the mesh ln-stretches (so a hand that does not move gets distinctness 1.0, ambiguous, rather
  than a ratio of round-off errors).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from typing_extensions import Unpack

from softsig_service.errors import InvalidInput, InvalidTrajectory
from softsig_service.geometry.ellipsoid import Ellipsoid, MveeOptions, mvee_batch, mvee_params
from softsig_service.geometry.pca import MomentOrigin, orient_axes, principal_components
from softsig_service.hands.trajectory import MIN_POINTS, ClosureTrajectory
from softsig_service.signatures.closure_types import (
    CRITERIA,
    DEFAULT_CRITERION,
    DEGENERATE_RTOL,
    DISTINCTNESS_CAP,
    ELLIPSOID_RESOLUTION_FACTOR,
    MESH_RESOLUTION,
    METHODS,
    NEARLY_EQUAL_RTOL,
    PCA_RESOLUTION_RTOL,
    ClosureSignature,
    Criterion,
    EllipsoidAxisSeries,
    MeshSource,
    Method,
)
from softsig_service.signatures.matrix_checks import float_list


def compute_closure_signature(
    traj: ClosureTrajectory,
    method: Method,
    *,
    pca_about: MomentOrigin = "zero",
    criterion: Criterion = DEFAULT_CRITERION,
    **mvee_options: Unpack[MveeOptions],
) -> ClosureSignature:
    """Closure signature of ``traj`` (positions [m], hand frame) by ``method``; every vector in the hand frame.

    ``mvee_options`` (``tol``, ``max_iter``, ``lift_epsilon``) configure the ellipsoid method's MVEE (see
    :mod:`softsig_service.geometry.ellipsoid`) and ``criterion`` its delta ("absolute" [m], the default, or
    "relative"); ``pca_about`` configures the pca method ("zero", the default of docs/design.md §4, or "mean").
    Parameters of the other methods are ignored: pca and mesh neither use the criterion nor record it in their
    ``params`` (only the ellipsoid method has one), but an unknown criterion is refused whatever the method. The mesh
    method uses ``traj.surface`` when present and otherwise the reference points (``params["source"]`` says
    which). Raises :class:`InvalidInput` for an unknown method or criterion and :class:`InvalidTrajectory` for
    unusable positions.
    """
    if method not in METHODS:
        raise InvalidInput("unknown closure-signature method", field="method", value=method, choices=METHODS)
    check_criterion(criterion)
    if method == "ellipsoid":
        return ellipsoid_closure_signature(traj.positions, criterion=criterion, **mvee_options)
    if method == "pca":
        return pca_closure_signature(traj.positions, about=pca_about)
    if traj.surface is not None:
        return mesh_closure_signature(traj.surface, source="surface")
    return mesh_closure_signature(traj.positions, source="reference_points")


def check_criterion(criterion: object) -> Criterion:
    """``criterion`` if it is one of :data:`CRITERIA`, else :class:`InvalidInput` naming the field ``criterion``."""
    if criterion == "absolute":
        return "absolute"
    if criterion == "relative":
        return "relative"
    raise InvalidInput("unknown ellipsoid criterion", field="criterion", value=criterion, choices=CRITERIA)


def ellipsoid_closure_signature(
    positions: ArrayLike, *, criterion: Criterion = DEFAULT_CRITERION, **mvee_options: Unpack[MveeOptions]
) -> ClosureSignature:
    """Ellipsoid-method CS of ``positions`` (T, N, 3) [m], hand frame; fits only E_0 and E_T.

    ``criterion`` "absolute" (the default): ``delta_k = a_k(T) - a_k(0)`` [m]; "relative":
    ``delta_k = (a_k(T) - a_k(0)) / a_k(0)`` (dimensionless). The CS is the axis of the largest |delta_k|;
    ``extras`` carry both changes per row of ``axes``. Raises :class:`InvalidInput` (field ``criterion``) for
    an unknown criterion.
    """
    criterion = check_criterion(criterion)
    p = _check_positions(positions, "positions", min_points=MIN_POINTS)
    mvee = mvee_params(mvee_options)
    fits = mvee_batch(p[[0, -1]], **mvee)
    e0, e_t = fits[0], fits[1]
    r = e0.axes.T  # rows r_k, E_0's semi-axes descending, sign rule applied
    a0 = e0.semi_axes
    a_t = np.sqrt(np.einsum("ki,ij,kj->k", r, e_t.inverse_shape(), r))
    absolute = a_t - a0
    relative = absolute / a0
    if criterion == "absolute":
        delta, unit = absolute, "m"
        largest = max(float(e0.semi_axes.max()), float(e_t.semi_axes.max()))
        resolution = ELLIPSOID_RESOLUTION_FACTOR * mvee["tol"] * largest
    else:
        delta, unit = relative, "1"
        resolution = ELLIPSOID_RESOLUTION_FACTOR * mvee["tol"]
    drift = r @ (e_t.center - e0.center)
    eligible = np.arange(3) < 3 - e0.n_lifted  # E_0's lifted axes are its smallest, listed last
    close_pairs = [
        (i, j) for i in range(3) for j in range(i + 1, 3)
        if eligible[i] and eligible[j] and a0[i] - a0[j] <= NEARLY_EQUAL_RTOL * a0[i]
    ]  # fmt: skip
    solver = {
        name: {"iterations": e.iterations, "converged": e.converged, "gap": e.gap}
        for name, e in (("initial", e0), ("final", e_t))
    }
    return _assemble(
        "ellipsoid",
        params={**mvee, "criterion": criterion},
        directions=r,
        deformation=delta,
        anchor=e0.center,
        per_axis={
            "absolute_change": absolute,
            "relative_change": relative,
            "centre_drift": drift,
            "half_width_initial": a0,
            "half_width_final": a_t,
        },
        resolution=resolution,
        extras={
            "magnitude_unit": unit,
            "lifted_epsilon": {"initial": e0.lifted_epsilon, "final": e_t.lifted_epsilon},
            "solver": solver,
            "n_frames": int(p.shape[0]),
            "n_points": int(p.shape[1]),
        },
        initial_ellipsoid=e0,
        final_ellipsoid=e_t,
        eligible=eligible,
        close_pairs=close_pairs,
    )


def ellipsoid_axis_series(positions: ArrayLike, **mvee_options: Unpack[MveeOptions]) -> EllipsoidAxisSeries:
    """Fit E_t for every frame of ``positions`` (T, N, 3) [m], hand frame; measure it along E_0's axes (docs/design.md
    §4, step 4): half-widths [m], their absolute [m] and relative changes, and the centre drift [m]."""
    p = _check_positions(positions, "positions", min_points=MIN_POINTS)
    fits = mvee_batch(p, **mvee_options)
    r = fits.axes[0].T  # rows
    semi_sq = fits.semi_axes**2  # (T, 3)
    # r_k^T A_t^-1 r_k with A_t^-1 = V_t diag(a_t^2) V_t^T
    proj = np.einsum("ki,tij->tkj", r, fits.axes)  # (T, k, j) = r_k . v_tj
    half = np.sqrt(np.einsum("tkj,tj->tk", proj**2, semi_sq))
    drift = (fits.center - fits.center[0]) @ r.T
    return EllipsoidAxisSeries(
        axes=r,
        half_widths=half,
        absolute_change=half - half[0],
        relative_change=half / half[0] - 1.0,
        centre_drift=drift,
        iterations=fits.iterations,
        converged=fits.converged,
        lifted_epsilon=fits.lifted_epsilon,
    )


def pca_closure_signature(positions: ArrayLike, *, about: MomentOrigin = "zero") -> ClosureSignature:
    """PCA-method CS of ``positions`` (T, N, 3) [m], hand frame: principal directions of the displacements."""
    p = _check_positions(positions, "positions", min_points=MIN_POINTS)
    disp = (p[1:] - p[0]).reshape(-1, 3)
    pc = principal_components(disp, about=about)
    return _assemble(
        "pca",
        params={"about": about},
        directions=pc.directions.T,
        deformation=pc.rms,
        anchor=p[0].mean(axis=0),
        per_axis={"explained_variance_ratio": pc.explained_variance_ratio},
        resolution=PCA_RESOLUTION_RTOL * float(np.abs(p).max()),
        extras={
            "magnitude_unit": "m",
            "rms_displacement": float(np.sqrt(np.mean(np.sum(disp**2, axis=1)))),
            "n_displacements": int(disp.shape[0]),
            "n_frames": int(p.shape[0]),
            "n_points": int(p.shape[1]),
        },
    )


def mesh_closure_signature(surface: ArrayLike, *, source: MeshSource = "surface") -> ClosureSignature:
    """Mesh-method CS of ``surface`` (T, M, 3) [m], hand frame, from its first and last frames.

    ``source`` ("surface" or "reference_points") only labels the result and the error fields. Raises
    :class:`InvalidTrajectory` when the initial points do not span 3-D (the affine map is then
    undetermined) or the fitted map squashes a direction to zero (a stretch of 0 has no logarithm). A map that
    mirrors the points (det F < 0) is flagged: a warning in ``extras["warnings"]``, and ``signed_stretches``
    gives the axis whose points crossed through zero its negative stretch.
    """
    if source not in ("surface", "reference_points"):
        raise InvalidInput("unknown mesh source", field="source", value=source, choices=("surface", "reference_points"))
    field_name = "surface" if source == "surface" else "positions"
    s = _check_positions(surface, field_name, min_points=MIN_POINTS)
    x0, x1 = s[0], s[-1]
    m0, m1 = x0.mean(axis=0), x1.mean(axis=0)
    y0, y1 = x0 - m0, x1 - m1
    sv0 = np.linalg.svd(y0, compute_uv=False)
    if not sv0[-1] > DEGENERATE_RTOL * sv0[0]:
        raise InvalidTrajectory(
            "the initial points are coplanar or collinear: the affine map of the mesh method is undetermined",
            field=f"{field_name}[0]",
            value=[float(v) for v in sv0],
        )
    ft, *_ = np.linalg.lstsq(y0, y1, rcond=None)
    f = ft.T
    b = m1 - f @ m0
    resid = np.linalg.norm(x0 @ f.T + b - x1, axis=1)
    w, stretch, vt = np.linalg.svd(f)
    if not stretch[-1] > DEGENERATE_RTOL * stretch[0]:
        raise InvalidTrajectory(
            "the fitted affine map squashes a direction to zero (the closed points are coplanar)",
            field=f"{field_name}[{s.shape[0] - 1}]",
            value=[float(v) for v in stretch],
        )
    det = float(np.linalg.det(f))
    signed = stretch.copy()
    notes: list[str] = []
    if det < 0.0:  # F = (W D)(D S) V^T, D = diag(1, 1, -1): a proper rotation and one stretch through zero
        signed[-1] = -signed[-1]
        w = w @ np.diag([1.0, 1.0, -1.0])
        notes.append(
            f"the fitted affine map mirrors the points (det F = {det:.3g} < 0): along one axis the points crossed "
            "through each other (fingers closing past one another), or two points' labels are swapped, or the "
            "frames differ in handedness; that axis's deformation (the log of |stretch|) understates its change "
            "(signed_stretches has its sign)"
        )
    rot = w @ vt
    cos_angle = float(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0))
    return _assemble(
        "mesh",
        params={"source": source},
        directions=vt,  # rows: eigenvectors of U = V S V^T
        deformation=np.log(stretch),
        anchor=m0,
        per_axis={"stretches": stretch, "signed_stretches": signed},
        resolution=MESH_RESOLUTION,
        notes=notes,
        extras={
            "magnitude_unit": "1",
            "fit_residual_rms": float(np.sqrt(np.mean(resid**2))),
            "fit_residual_max": float(resid.max()),
            "det_F": det,
            "rotation_angle": math.acos(cos_angle),
            "affine_matrix": [float_list(row) for row in f],
            "affine_offset": float_list(b),
            "n_frames": int(s.shape[0]),
            "n_points": int(s.shape[1]),
        },
    )


def distinctness_ratio(deformation: ArrayLike, resolution: float = 0.0) -> float:
    """|d_(1)| / |d_(2)| of the two largest |deformation| values, capped at :data:`DISTINCTNESS_CAP`.

    Values with |d| <= ``resolution`` (same unit as ``deformation``) count as 0: 1.0 when every value does
    (nothing distinguishes any axis), the cap when only the second does.
    """
    mags = np.sort(np.abs(np.asarray(deformation, dtype=np.float64)))[::-1]
    first, second = float(mags[0]), float(mags[1])
    if first <= resolution:
        return 1.0
    if second <= resolution or second * DISTINCTNESS_CAP <= first:
        return DISTINCTNESS_CAP
    return first / second


def _assemble(
    method: Method,
    *,
    params: dict[str, Any],
    directions: NDArray[np.float64],
    deformation: NDArray[np.float64],
    anchor: NDArray[np.float64],
    per_axis: dict[str, NDArray[np.float64]],
    extras: dict[str, Any],
    resolution: float,
    initial_ellipsoid: Ellipsoid | None = None,
    final_ellipsoid: Ellipsoid | None = None,
    eligible: NDArray[np.bool_] | None = None,
    close_pairs: Sequence[tuple[int, int]] = (),
    notes: Sequence[str] = (),
) -> ClosureSignature:
    """Order the axes by |deformation| descending (axes not ``eligible`` for election after the others), apply
    the sign rule and build the signature. ``close_pairs`` (indices into ``directions``) are reported as
    ill-defined, with the indices they get in the ordered ``axes``; ``notes`` are warnings of the method itself."""
    ok = np.ones(len(deformation), dtype=bool) if eligible is None else np.asarray(eligible, dtype=bool)
    order = np.lexsort((-np.abs(deformation), ~ok))  # eligible first, then |deformation| descending
    axes = orient_axes(directions[order])
    deformation = np.asarray(deformation[order], dtype=np.float64)
    # per-axis quantities that change sign with the axis (the centre drift) follow the flip
    flips = np.sign(np.einsum("ki,ki->k", axes, directions[order]))
    all_extras = dict(extras)
    all_extras["resolution"] = float(resolution)
    for key, values in per_axis.items():
        vals = values[order] * flips if key == "centre_drift" else values[order]
        all_extras[key] = float_list(vals)
    rank = {int(k): i for i, k in enumerate(order)}
    warnings: list[str] = list(notes)
    if not ok.all():
        all_extras["lifted_axes"] = sorted(rank[int(k)] for k in np.flatnonzero(~ok))
        warnings.append("the open points are coplanar or collinear: axes that exist only by lifting are not elected")
    if close_pairs:
        all_extras["ill_defined_axes"] = [sorted((rank[i], rank[j])) for i, j in close_pairs]
        warnings.append("two semi-axes of the open hand's ellipsoid are nearly equal: their directions are ill-defined")
    if warnings:
        all_extras["warnings"] = warnings
    distinct = deformation[: max(int(ok.sum()), 2)] if ok.sum() >= 2 else np.append(deformation[:1], 0.0)
    return ClosureSignature(
        method=method,
        params=params,
        axis=axes[0].copy(),
        anchor=np.asarray(anchor, dtype=np.float64).copy(),
        magnitude=float(deformation[0]),
        deformation=deformation,
        axes=axes,
        distinctness=distinctness_ratio(distinct, resolution),
        initial_ellipsoid=initial_ellipsoid,
        final_ellipsoid=final_ellipsoid,
        extras=all_extras,
    )


def _check_positions(positions: ArrayLike, field_name: str, *, min_points: int) -> NDArray[np.float64]:
    """``positions`` as a finite (T >= 2, N >= min_points, 3) float array, else :class:`InvalidTrajectory`."""
    try:
        p = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidTrajectory(f"{field_name} must be a (T, N, 3) array of numbers", field=field_name) from exc
    if p.ndim != 3 or p.shape[2] != 3:
        raise InvalidTrajectory(f"{field_name} must have shape (T, N, 3)", field=field_name, value=list(p.shape))
    if p.shape[0] < 2:
        raise InvalidTrajectory(
            "at least 2 frames (open and closed) are needed", field=field_name, value=int(p.shape[0])
        )
    if p.shape[1] < min_points:
        raise InvalidTrajectory(f"at least {min_points} points are needed", field=field_name, value=int(p.shape[1]))
    finite = np.isfinite(p)
    if not np.all(finite):
        t, i, _ = (int(v) for v in np.argwhere(~finite)[0])
        raise InvalidTrajectory(
            f"{field_name} must be finite (no NaN or infinity)",
            field=f"{field_name}[{t}][{i}]",
            value=[float(v) if math.isfinite(v) else None for v in p[t, i]],
        )
    return p
