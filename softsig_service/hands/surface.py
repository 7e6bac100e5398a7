"""Deterministic, near-uniform samples of a hand's surface, in each geom's own frame.

Used by the mesh method of the closure signature: the samples are fixed in their geom and tracked through a
closure. Mesh geoms contribute (a regular subset of) their vertices; primitives are sampled on their surface
with spacing set by the requested total count, shared out by surface area. Units: [m].
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from numpy.typing import NDArray

_GOLDEN = math.pi * (3.0 - math.sqrt(5.0))


def fibonacci_sphere(n: int) -> NDArray[np.float64]:
    """``n`` near-uniform unit vectors (Fibonacci lattice), shape (n, 3)."""
    k = np.arange(n, dtype=np.float64) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(np.clip(1.0 - z * z, 0.0, 1.0))
    phi = _GOLDEN * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _disk(n: int, radius: float, z: float) -> NDArray[np.float64]:
    k = np.arange(n, dtype=np.float64) + 0.5
    r = radius * np.sqrt(k / n)
    phi = _GOLDEN * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(n, z)])


def _tube(n: int, radius: float, half: float) -> NDArray[np.float64]:
    rows = max(2, round(math.sqrt(n * (2 * half) / (2 * math.pi * radius + 1e-12))))
    cols = max(3, math.ceil(n / rows))
    zz = np.linspace(-half, half, rows)
    phi = np.linspace(0.0, 2 * math.pi, cols, endpoint=False)
    P, Z = np.meshgrid(phi, zz)
    return np.column_stack([radius * np.cos(P).ravel(), radius * np.sin(P).ravel(), Z.ravel()])


def _box(n: int, half: NDArray[np.float64]) -> NDArray[np.float64]:
    areas = np.array([half[1] * half[2], half[0] * half[2], half[0] * half[1]])
    pts = []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        count = max(1, round(n * areas[axis] / (2 * areas.sum())))
        side = max(2, round(math.sqrt(count * half[u] / max(half[v], 1e-12))))
        other = max(2, math.ceil(count / side))
        gu, gv = np.meshgrid(np.linspace(-half[u], half[u], side), np.linspace(-half[v], half[v], other))
        for sign in (-1.0, 1.0):
            face = np.zeros((gu.size, 3))
            face[:, u] = gu.ravel()
            face[:, v] = gv.ravel()
            face[:, axis] = sign * half[axis]
            pts.append(face)
    return np.vstack(pts)


def _area(gtype: int, size: NDArray[np.float64]) -> float:
    if gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
        return 4 * math.pi * size[0] ** 2
    if gtype == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return 4 * math.pi * size[0] ** 2 + 4 * math.pi * size[0] * size[1]
    if gtype == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return 2 * math.pi * size[0] ** 2 + 4 * math.pi * size[0] * size[1]
    if gtype == mujoco.mjtGeom.mjGEOM_BOX:
        return 8 * (size[0] * size[1] + size[1] * size[2] + size[0] * size[2])
    if gtype == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        a, b, c = size  # Knud Thomsen's approximation
        p = 1.6075
        return 4 * math.pi * (((a * b) ** p + (a * c) ** p + (b * c) ** p) / 3) ** (1 / p)
    return 0.0


def sample_geom(model: mujoco.MjModel, geom: int, n: int) -> NDArray[np.float64]:
    """About ``n`` surface points of geom ``geom`` in its own frame [m], shape (m, 3); planes give none."""
    gtype = int(model.geom_type[geom])
    size = np.asarray(model.geom_size[geom], dtype=np.float64)
    n = max(n, 4)
    if gtype == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = int(model.geom_dataid[geom])
        start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        verts = np.asarray(model.mesh_vert[start : start + count], dtype=np.float64)
        step = max(1, count // n)
        return verts[::step]
    if gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
        return size[0] * fibonacci_sphere(n)
    if gtype == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return size[:3] * fibonacci_sphere(n)
    if gtype == mujoco.mjtGeom.mjGEOM_CAPSULE:
        r, h = size[0], size[1]
        cap_share = r / (r + h)
        sphere = r * fibonacci_sphere(max(4, round(n * cap_share)))
        sphere[:, 2] += np.where(sphere[:, 2] >= 0, h, -h)
        return np.vstack([sphere, _tube(max(4, n - len(sphere)), r, h)])
    if gtype == mujoco.mjtGeom.mjGEOM_CYLINDER:
        r, h = size[0], size[1]
        caps = max(2, round(n * r / (2 * (r + 2 * h))))
        return np.vstack([_disk(caps, r, h), _disk(caps, r, -h), _tube(max(4, n - 2 * caps), r, h)])
    if gtype == mujoco.mjtGeom.mjGEOM_BOX:
        return _box(n, size)
    return np.zeros((0, 3))


def hand_surface_samples(model: mujoco.MjModel, total: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Samples over every geom not on the world body: (geom index per point (M,), local points (M, 3) [m])."""
    geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0]
    areas = np.array(
        [
            _area(int(model.geom_type[g]), np.asarray(model.geom_size[g]))
            if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH
            else float(model.geom_rbound[g]) ** 2 * 4 * math.pi
            for g in geoms
        ]
    )
    if total <= 0 or not geoms or areas.sum() <= 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 3))
    idx, pts = [], []
    for g, a in zip(geoms, areas, strict=True):
        local = sample_geom(model, g, round(total * a / areas.sum()))
        idx.append(np.full(len(local), g, dtype=np.int64))
        pts.append(local)
    return np.concatenate(idx), np.vstack(pts)
