"""Request and response bodies of ``POST /v1/segmentations``: a tabletop cloud in, the table and its objects out.

Same conventions as :mod:`softsig_service.api.schemas` (strict requests, closed responses, SI units, ``base_link``).
"""

from __future__ import annotations

from pydantic import Field

from softsig_service.api.schemas import Out, Vector3
from softsig_service.objects.schema import (
    MAX_TABLETOP_POINTS,
    WORLD_FRAME,
    Coordinate,
    FrameId,
    Integer,
    SceneFields,
)


class SegmentationIn(SceneFields):
    """A whole tabletop cloud (table and objects) in ``frame_id`` (``base_link`` or a frame of ``frames``)."""

    points: list[tuple[Coordinate, Coordinate, Coordinate]] = Field(min_length=20, max_length=MAX_TABLETOP_POINTS)
    frame_id: FrameId = WORLD_FRAME
    plane_tolerance: float = Field(0.008, ge=0.001, le=0.05, strict=True, description="[m] table inliers")
    cluster_distance: float = Field(0.015, ge=0.002, le=0.1, strict=True, description="[m] DBSCAN radius")
    min_points: Integer = Field(50, ge=4, le=100_000, strict=True, description="smallest cluster [points]")
    filter_outliers: bool = Field(True, strict=True, description="drop statistical outliers of each cluster")


class TableOut(Out):
    """The table plane found: ``height`` [m] (mean over its inliers), unit ``normal``, ``tilt`` [rad] from
    horizontal, ``inliers`` (points on it)."""

    height: float
    normal: Vector3
    tilt: float
    inliers: int


class SolidOut(Out):
    """A cluster's conservative solid: triangle ``vertices`` [m] (base_link) and ``faces``; usable as the object
    of a plan (``{"kind": "mesh", ...}``)."""

    vertices: list[tuple[float, float, float]]
    faces: list[tuple[int, int, int]]
    volume: float = Field(description="[m^3]")


class ClusterOut(Out):
    """One object on the table: ``index`` (largest first; ``pick.index`` of a tabletop object), its point count,
    ``centroid`` [m], its solid's principal horizontal axes ``o1`` (major) and ``o2``, footprint extents
    ``extent_major`` and ``extent_minor`` [m], ``height`` [m], and the solid."""

    index: int
    points: int
    centroid: Vector3
    o1: Vector3
    o2: Vector3
    extent_major: float
    extent_minor: float
    height: float
    solid: SolidOut


class SegmentationOut(Out):
    """The table, the clusters on it, and the points left as noise (above the table, in no cluster)."""

    table: TableOut
    clusters: list[ClusterOut]
    noise: int
