"""The MuJoCo shape of a table object: one mapping from an object primitive to a geom, shared by every scene."""

from __future__ import annotations

import mujoco
import numpy as np

from softsig_service.objects import ShapePrimitive

GEOM_TYPES = {
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "ellipsoid": mujoco.mjtGeom.mjGEOM_ELLIPSOID,
}


def set_object_shape(spec: mujoco.MjSpec, geom: mujoco.MjsGeom, prim: ShapePrimitive, mesh_name: str) -> None:
    """Give ``geom`` the shape of ``prim`` (MuJoCo size conventions, [m]); a mesh is added to ``spec``."""
    if prim.kind == "mesh":
        assert prim.vertices is not None and prim.faces is not None
        mesh = spec.add_mesh(name=mesh_name)
        mesh.uservert = np.asarray(prim.vertices, dtype=np.float64).ravel().tolist()
        mesh.userface = np.asarray(prim.faces, dtype=np.int64).ravel().tolist()
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = mesh_name
        return
    geom.type = GEOM_TYPES[prim.kind]
    geom.size = list(prim.size) + [0.0] * (3 - len(prim.size))
