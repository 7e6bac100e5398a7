"""A segmented point cloud of one object as the solid softsig plans and simulates with: the conservative solid.

A camera sees an object from one side: its back and its underside are unseen. softsig takes the **convex hull of
the points together with their projection onto the table plane** (every point ``(x, y, z)`` also as ``(x, y,
table_height)``). That solid contains every part of a convex object the camera saw and everything the camera could
not see below those parts: a grasp planned clear of it is clear of the object, and the hand closing on it closes
on the real object no later than on the solid. Its limits:

- **concave objects** (a mug's opening, a banana's inner curve) become their convex hull: the planner never puts a
  finger inside a concavity, and the simulation holds the object by its hull (MuJoCo collides meshes as their
  convex hulls anyway);
- **overhangs** (a handle sticking out above the table) are filled down to the table;
- **the unseen back** is bounded by the seen points only: an object deeper than what the camera saw is shorter in
  the solid than in reality (a second view, merged into one cloud in ``base_link``, restores it);
- **outliers** (flying pixels at depth edges, a speck of the table left by the segmentation) would inflate the hull,
  so a statistical outlier filter runs first: a point whose mean distance to its ``OUTLIER_NEIGHBOURS`` nearest
  neighbours exceeds the cloud's mean of that distance by more than ``OUTLIER_STD_RATIO`` standard deviations is
  dropped (the rule of PCL's and Open3D's statistical outlier removal; scipy's k-d tree);
- **heavy noise** makes the solid larger by about the noise's amplitude (a hull is as large as its outermost
  points): a D435-like camera at 0.5-0.8 m (depth noise of a few mm) gives solids a few mm larger than the object.

Points below the table plane (noise of the table itself) are lifted onto it. A cloud whose solid is thinner than
:data:`MIN_THICKNESS` in some direction (a sheet on the table, one face seen exactly edge-on) is refused: there is
nothing the planner could close on.

Units: metres, in ``base_link`` (z up; the table top is ``z = table_height``). The hull is qhull's (scipy). Pure
geometry: no MuJoCo, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

MIN_POINTS = 4
"""Fewest points of a cloud (after the outlier filter): a solid needs four points not in one plane."""
MAX_POINTS = 200_000
"""Most points of a cloud."""
MIN_THICKNESS = 0.002
"""Thinnest solid [m] (2 mm) across its narrowest direction: below it the cloud is flat and nothing can be grasped."""
OUTLIER_NEIGHBOURS = 16
"""Neighbours of the statistical outlier filter (PCL's and Open3D's customary 10-50)."""
OUTLIER_STD_RATIO = 2.0
"""Standard deviations above the mean neighbour distance beyond which a point is an outlier (customary 1-3)."""


@dataclass(frozen=True)
class CloudSolid:
    """The conservative solid of a cloud.

    Attributes:
        vertices: ``(N, 3)`` [m] hull vertices in ``base_link``. faces: ``(M, 3)`` triangles, outward-facing.
        points_used: points that entered the hull (after the outlier filter). outliers: points the filter dropped.
        lifted: points that lay below the table plane and were lifted onto it.
        volume: [m^3] of the solid. thickness: [m] its narrowest width (minimum over its face normals).
    """

    vertices: FloatArray
    faces: IntArray
    points_used: int
    outliers: int
    lifted: int
    volume: float
    thickness: float


def statistical_outliers(
    points: FloatArray, neighbours: int = OUTLIER_NEIGHBOURS, std_ratio: float = OUTLIER_STD_RATIO
) -> NDArray[np.bool_]:
    """Mask ``(N,)`` of the outliers of ``points`` ``(N, 3)`` [m]: points whose mean distance to their
    ``neighbours`` nearest neighbours exceeds the cloud's mean of that distance by more than ``std_ratio`` standard
    deviations (PCL's and Open3D's statistical outlier removal). A cloud of ``neighbours`` points or fewer has
    none."""
    from scipy.spatial import cKDTree

    if len(points) <= neighbours:
        return np.zeros(len(points), dtype=bool)
    d, _ = cKDTree(points).query(points, k=neighbours + 1, workers=-1)
    mean = d[:, 1:].mean(axis=1)  # the nearest is the point itself
    return np.asarray(mean > mean.mean() + std_ratio * mean.std(), dtype=bool)


def conservative_solid(
    points: FloatArray, table_height: float = 0.0, *, filter_outliers: bool = True, field: str = "object.points"
) -> CloudSolid:
    """The conservative solid (module docstring) of ``points`` ``(N, 3)`` [m] in ``base_link`` over the table at
    ``table_height`` [m]. Raises :class:`InvalidInput` naming ``field`` for too few or too many points,
    non-finite coordinates, or a flat cloud."""
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise InvalidInput("expected points as [[x, y, z], ...]", field=field, value=list(P.shape))
    if len(P) < MIN_POINTS:
        raise InvalidInput(f"a cloud needs at least {MIN_POINTS} points", field=field, value=len(P))
    if len(P) > MAX_POINTS:
        raise InvalidInput(f"a cloud has at most {MAX_POINTS} points", field=field, value=len(P))
    if not np.all(np.isfinite(P)):
        row = int(np.argwhere(~np.isfinite(P))[0][0])
        raise InvalidInput("every coordinate must be a finite number", field=f"{field}[{row}]")
    below = P[:, 2] < table_height
    P = P.copy()
    P[below, 2] = table_height
    outliers = statistical_outliers(P) if filter_outliers else np.zeros(len(P), dtype=bool)
    kept = P[~outliers]
    if len(kept) < MIN_POINTS:
        raise InvalidInput(
            f"fewer than {MIN_POINTS} points remain after the outlier filter", field=field, value=len(kept)
        )
    hull = _hull(kept, table_height)
    thickness = _thickness(hull) if hull is not None else 0.0
    if hull is None or thickness < MIN_THICKNESS:
        raise InvalidInput(
            f"the points and their projection on the table span a solid {thickness * 1000:.1f} mm thin at its "
            f"narrowest (at least {MIN_THICKNESS * 1000:.0f} mm): the cloud is flat (a sheet on the table, or one "
            "face seen edge-on; add a view)",
            field=field,
            value=round(thickness, 6),
        )
    vertices, faces = _outward_mesh(hull)
    return CloudSolid(
        vertices=vertices,
        faces=faces,
        points_used=len(kept),
        outliers=int(outliers.sum()),
        lifted=int(below.sum()),
        volume=float(hull.volume),
        thickness=thickness,
    )


def _hull(points: FloatArray, table_height: float) -> Any:
    """scipy's (qhull's) convex hull of ``points`` and their footprint on the table (points first, then their
    footprints, in the same order), or None when they span no volume."""
    from scipy.spatial import ConvexHull, QhullError

    foot = points.copy()
    foot[:, 2] = table_height
    try:
        return ConvexHull(np.vstack([points, foot]))
    except QhullError:  # coplanar or collinear input
        return None


def _outward_mesh(hull: Any) -> tuple[FloatArray, IntArray]:
    """The hull's vertices and triangles, renumbered over its vertices and wound so that their normals point out."""
    used = np.asarray(hull.vertices)
    renumber = np.full(len(hull.points), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    V = np.asarray(hull.points[used], dtype=np.float64)
    F = renumber[np.asarray(hull.simplices)]
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), hull.equations[:, :3]) < 0.0
    F[inward] = F[inward][:, ::-1]
    return V, F


def _thickness(hull: Any) -> float:
    """Width [m] of a convex hull across its flattest direction: the least, over its facets' normals, of its extent
    along the normal. A flat solid has a facet whose normal is across it, so this is near zero for one; the true
    minimum width may also lie along an edge-edge direction, so for a sliver seen diagonally it can be larger."""
    V = np.asarray(hull.points[hull.vertices])
    return float(np.ptp(V @ hull.equations[:, :3].T, axis=0).min())
