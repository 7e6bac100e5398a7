"""The collision geometry of a hand's open posture as primitives in the hand frame (for the arm's coal world).

Capsules, boxes, spheres and cylinders are taken as they are; ellipsoids become their bounding sphere and
meshes their oriented bounding box (both conservative). Geoms that collide with nothing (contype and
conaffinity both 0) are skipped.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from softsig_service.arm.shapes import HandShape
from softsig_service.hands.closure import prepare_data, to_hand_frame
from softsig_service.hands.model import HandModel


def hand_collision_shapes(hand: HandModel) -> list[HandShape]:
    """Primitives of the open hand, posed in the hand frame [m]."""
    model = copy.copy(hand.model)
    data = prepare_data(hand, model)
    R_mount = data.xmat[hand.mount_body].reshape(3, 3)
    shapes: list[HandShape] = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == 0 or (model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0):
            continue
        gtype = int(model.geom_type[g])
        size = np.asarray(model.geom_size[g], dtype=float)
        T = np.eye(4)
        T[:3, :3] = R_mount.T @ data.geom_xmat[g].reshape(3, 3)
        T[:3, 3] = to_hand_frame(hand, data, data.geom_xpos[g])
        name = model.geom(g).name or f"geom{g}"
        if gtype == mujoco.mjtGeom.mjGEOM_BOX:
            shapes.append(HandShape("box", tuple(size), T, name))
        elif gtype == mujoco.mjtGeom.mjGEOM_CAPSULE:
            shapes.append(HandShape("capsule", (size[0], size[1]), T, name))
        elif gtype == mujoco.mjtGeom.mjGEOM_CYLINDER:
            shapes.append(HandShape("cylinder", (size[0], size[1]), T, name))
        elif gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
            shapes.append(HandShape("sphere", (size[0],), T, name))
        elif gtype == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
            shapes.append(HandShape("sphere", (float(size.max()),), T, name))
        elif gtype == mujoco.mjtGeom.mjGEOM_MESH:
            aabb = np.asarray(model.geom_aabb[g], dtype=float)  # centre (3), half sizes (3), geom frame
            offset = np.eye(4)
            offset[:3, 3] = aabb[:3]
            shapes.append(HandShape("box", tuple(np.maximum(aabb[3:], 1e-4)), T @ offset, name))
    return shapes
