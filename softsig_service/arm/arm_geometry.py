"""The UR5's collision geometry (coal, through Pinocchio): link meshes replaced by their convex hulls, built once
per process, and the link pairs the SRDF leaves enabled.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from softsig_service.arm.shapes import (
    convex_hull,
)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ArmGeometry:
    model: pin.GeometryModel  # arm links with convex hulls, no pairs
    names: tuple[str, ...]  # link name of each geometry object
    self_pairs: tuple[tuple[int, int], ...]  # SRDF-filtered


def link_name(geom_name: str) -> str:
    """``"wrist_2_link_0"`` -> ``"wrist_2_link"`` (Pinocchio suffixes geometry names with an index)."""
    head, sep, tail = geom_name.rpartition("_")
    return head if sep and tail.isdigit() else geom_name


@lru_cache(maxsize=4)
def arm_geometry(urdf: Path, srdf: Path, package_dir: Path) -> ArmGeometry:
    """Arm collision geometry (convex hulls of the link meshes) and its SRDF-filtered pairs, built once."""
    model = pin.buildModelFromUrdf(str(urdf))
    gm = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(package_dir)])
    for go in gm.geometryObjects:
        geo = go.geometry
        if isinstance(geo, coal.BVHModelBase):
            go.geometry = convex_hull(np.array(geo.vertices()), field=go.name)
    gm.addAllCollisionPairs()
    pin.removeCollisionPairs(model, gm, str(srdf))
    pairs = tuple((int(cp.first), int(cp.second)) for cp in gm.collisionPairs)
    names = tuple(link_name(go.name) for go in gm.geometryObjects)
    return ArmGeometry(gm, names, pairs)
