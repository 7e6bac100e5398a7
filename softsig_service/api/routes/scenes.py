"""``POST /v1/segmentations``: a whole tabletop cloud split into the table and the objects on it, so that a robot
stack can show it and choose a target (``pick.index`` of a ``tabletop`` object)."""

from __future__ import annotations

from typing import Any

import numpy as np
from fastapi import APIRouter
from starlette.concurrency import run_in_threadpool

from softsig_service.api.deps import Ctx
from softsig_service.api.routes.common import write_route
from softsig_service.api.scene import scene_frames
from softsig_service.api.scene_schemas import SegmentationIn, SegmentationOut
from softsig_service.services.serialize import vector_json

router = APIRouter(prefix="/v1", tags=["plans"])


def _segment(body: SegmentationIn) -> dict[str, Any]:
    from softsig_service.objects.frames import to_world
    from softsig_service.objects.parse import segmentation_of, solid_object

    frames = scene_frames(body)
    points = to_world(np.asarray(body.points, dtype=np.float64), body.frame_id, frames, "frame_id")
    seg = segmentation_of(points, body, "points")
    clusters = []
    for c in seg.clusters:
        obj = solid_object(c.solid, seg.height, 1.0, 1.0, f"cluster_{c.index}")
        clusters.append({
            "index": c.index, "points": len(c.points), "centroid": vector_json(c.centroid), "o1": vector_json(obj.o1),
            "o2": vector_json(obj.o2), "extent_major": obj.extent_major, "extent_minor": obj.extent_minor,
            "height": obj.height,
            "solid": {"vertices": c.solid.vertices.tolist(), "faces": c.solid.faces.tolist(), "volume": c.solid.volume},
        })  # fmt: skip
    table = {"height": seg.height, "normal": vector_json(seg.normal), "tilt": seg.tilt, "inliers": seg.inliers}
    return {"table": table, "clusters": clusters, "noise": seg.noise}


@router.post(
    "/segmentations",
    response_model=SegmentationOut,
    **write_route(),
    summary="Split a tabletop cloud into the table and its objects",
)
async def create_segmentation(ctx: Ctx, body: SegmentationIn) -> dict[str, Any]:
    """Find the table plane (RANSAC), cluster what stands on it (DBSCAN) and give each cluster's conservative solid,
    axes and extents (docs/objects.md). Nothing is stored; 422 naming the field when no horizontal table holds
    enough of the points or nothing stands on it."""
    return await run_in_threadpool(_segment, body)
