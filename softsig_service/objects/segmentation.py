"""A whole tabletop cloud, as a depth camera sees it, split into the table and the objects on it.

1. **The table**: the plane ``z = a x + b y + c`` fitted by RANSAC (scikit-learn's ``RANSACRegressor``, inliers
   within ``plane_tolerance`` [m]) to the points in ``base_link``. A table is horizontal in ``base_link``: a plane
   tilted by more than :data:`MAX_TILT` is refused (the camera's pose in ``frames`` is wrong, or there is no table
   in view), and so is a plane holding fewer than :data:`MIN_TABLE_SHARE` of the points. Its height is the plane's
   mean height over its inliers.
2. **The objects**: the points more than ``plane_tolerance`` above the plane, clustered by DBSCAN (scikit-learn)
   over voxels of ``cluster_distance / 2`` weighted by their points (voxels whose centres are closer than
   ``cluster_distance`` [m] join a cluster; a core voxel's neighbourhood holds :data:`MIN_SAMPLES` points), so that
   memory stays bounded for a close-up of one large object.
   Clusters of fewer than ``min_points`` points are noise. Clusters are numbered by size, largest first (ties by
   their centroid's x, then y), so a scene gives the same numbers every time.
3. **Their solids**: each cluster becomes its conservative solid on the table (:mod:`softsig_service.objects.cloud`);
   a flat cluster (thinner than the solid rule admits: a card seen edge-on) is left as noise.

Units: metres, ``base_link`` (z up). The target of a plan is then picked by index or as the cluster whose centroid
is nearest a given point; the other clusters are its obstacles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput
from softsig_service.objects.cloud import MIN_POINTS, CloudSolid, conservative_solid

FloatArray = NDArray[np.float64]

MAX_TILT = math.radians(10.0)
"""Largest tilt [rad] of the table plane from horizontal in ``base_link``."""
MIN_TABLE_SHARE = 0.1
"""Least share of the cloud's points the table plane must hold."""
PLANE_TOLERANCE = 0.008
"""Default [m]: points within this of the plane are the table's (a D435-like depth noise at 0.5-0.8 m is a few mm,
approximate)."""
CLUSTER_DISTANCE = 0.015
"""Default [m]: DBSCAN's neighbourhood radius (objects closer than this to each other merge)."""
MIN_SAMPLES = 10
"""DBSCAN's neighbours of a core point."""
MIN_CLUSTER_POINTS = 50
"""Default: smaller clusters are noise."""


@dataclass(frozen=True)
class Cluster:
    """One object of a tabletop: its points [m] in ``base_link``, their centroid, and its conservative solid."""

    index: int
    points: FloatArray
    centroid: FloatArray
    solid: CloudSolid


@dataclass(frozen=True)
class Segmentation:
    """A tabletop split: the table plane (``height`` [m], unit ``normal``, ``tilt`` [rad], ``inliers`` its point
    count), the clusters (largest first) and how many points were left as noise."""

    height: float
    normal: FloatArray
    tilt: float
    inliers: int
    clusters: list[Cluster] = field(default_factory=list)
    noise: int = 0


def segment_tabletop(
    points: FloatArray,
    *,
    plane_tolerance: float = PLANE_TOLERANCE,
    cluster_distance: float = CLUSTER_DISTANCE,
    min_points: int = MIN_CLUSTER_POINTS,
    filter_outliers: bool = True,
    field: str = "points",
) -> Segmentation:
    """The table and the objects of the cloud ``points`` ``(N, 3)`` [m] in ``base_link`` (module docstring).
    Raises :class:`InvalidInput` naming ``field`` when no horizontal table plane holds enough of the points, or
    when nothing stands on it."""
    from sklearn.linear_model import LinearRegression, RANSACRegressor

    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < MIN_SAMPLES * 2:
        raise InvalidInput(f"a tabletop cloud needs at least {MIN_SAMPLES * 2} points [[x, y, z], ...]", field=field)
    if not np.all(np.isfinite(P)):
        raise InvalidInput(
            "every coordinate must be a finite number", field=f"{field}[{int(np.argwhere(~np.isfinite(P))[0][0])}]"
        )
    ransac = RANSACRegressor(
        LinearRegression(), residual_threshold=plane_tolerance, random_state=0, max_trials=200
    ).fit(P[:, :2], P[:, 2])
    inliers = np.asarray(ransac.inlier_mask_, dtype=bool)
    a, b = (float(v) for v in ransac.estimator_.coef_)
    normal = np.array([-a, -b, 1.0]) / math.sqrt(a * a + b * b + 1.0)
    tilt = math.acos(min(1.0, float(normal[2])))
    if inliers.sum() < MIN_TABLE_SHARE * len(P):
        raise InvalidInput(
            f"no table plane: the best plane holds {int(inliers.sum())} of {len(P)} points "
            f"(at least {MIN_TABLE_SHARE:.0%} are needed)",
            field=field,
        )
    if tilt > MAX_TILT:
        raise InvalidInput(
            f"the dominant plane is tilted by {math.degrees(tilt):.1f} deg in base_link (at most "
            f"{math.degrees(MAX_TILT):.0f}): not a table, or the camera's pose in frames is wrong",
            field=field,
            value=round(math.degrees(tilt), 2),
        )
    height = float(P[inliers, 2].mean())
    above = P[~inliers]
    if len(above):
        above = above[above[:, 2] > ransac.predict(above[:, :2]) + plane_tolerance]
    labels = _voxel_dbscan(above, cluster_distance) if len(above) else np.array([], dtype=np.int64)
    groups = [above[labels == k] for k in np.unique(labels[labels >= 0])]
    groups = [g for g in groups if len(g) >= max(min_points, MIN_POINTS)]
    if not groups:
        raise InvalidInput("nothing stands on the table: no cluster of points above its plane", field=field)
    groups.sort(key=lambda g: (-len(g), float(g[:, 0].mean()), float(g[:, 1].mean())))
    clusters: list[Cluster] = []
    for g in groups:
        try:
            solid = conservative_solid(g, height, filter_outliers=filter_outliers, field=field)
        except InvalidInput:  # a flat cluster (a card seen edge-on, a sheet): nothing to grasp or hit, left as noise
            continue
        clusters.append(Cluster(index=len(clusters), points=g, centroid=g.mean(axis=0), solid=solid))
    if not clusters:
        raise InvalidInput("nothing stands on the table: every cluster above its plane is flat", field=field)
    noise = int(len(above) - sum(len(c.points) for c in clusters))
    return Segmentation(height=height, normal=normal, tilt=tilt, inliers=int(inliers.sum()), clusters=clusters,
                        noise=noise)  # fmt: skip


def _voxel_dbscan(points: FloatArray, eps: float) -> NDArray[np.int64]:
    """DBSCAN labels of ``points`` (-1: noise), clustered as the centres of the occupied voxels of side ``eps / 2``,
    each weighted by its point count (scikit-learn's ``sample_weight``: a core voxel holds or neighbours at least
    :data:`MIN_SAMPLES` points), the labels mapped back to the points. DBSCAN keeps every neighbourhood in memory:
    over raw points a close-up of one large object would hold billions of pairs; over voxels, a few per voxel."""
    from sklearn.cluster import DBSCAN

    keys, inverse, counts = np.unique(np.floor(points / (0.5 * eps)).astype(np.int64), axis=0, return_inverse=True,
                                      return_counts=True)  # fmt: skip
    centres = (keys + 0.5) * (0.5 * eps)
    labels = DBSCAN(eps=eps, min_samples=MIN_SAMPLES).fit_predict(centres, sample_weight=counts)
    return np.asarray(labels[inverse.ravel()], dtype=np.int64)


def pick_target(segmentation: Segmentation, *, index: int | None, near: FloatArray | None, field: str) -> int:
    """The index of the target cluster: ``index`` itself, or the cluster whose centroid is nearest ``near`` [m]
    (default: the largest, index 0). Raises :class:`InvalidInput` naming ``field`` for an index out of range."""
    n = len(segmentation.clusters)
    if index is not None:
        if not 0 <= index < n:
            raise InvalidInput(f"the tabletop has {n} clusters (0 to {n - 1})", field=f"{field}.index", value=index)
        return index
    if near is not None:
        d = [float(np.linalg.norm(c.centroid - near)) for c in segmentation.clusters]
        return int(np.argmin(d))
    return 0
