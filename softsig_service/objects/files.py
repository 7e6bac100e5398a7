"""Objects from files: meshes (STL binary or ASCII, OBJ, PLY) and point clouds (PCD, PLY without faces), read with
trimesh and pypcd4, as the object JSON of :func:`~softsig_service.objects.object_from_json`.

A mesh keeps its file's axes (z up as given) and is placed on the table like any mesh; ``scale`` multiplies its
coordinates (a CAD file in millimetres takes ``scale = 0.001``). A cloud's points are in ``frame_id`` and become a
``points`` object (its conservative solid, :mod:`softsig_service.objects.cloud`); non-finite points, which PCD files
of organised clouds use for pixels without depth, are left out. Refusals are :class:`InvalidInput` naming
``field``: an unknown suffix (with the choices), a file that does not parse, an empty one, or one over the
schema's limits.
"""

from __future__ import annotations

import io
from pathlib import PurePath
from typing import Any

import numpy as np

from softsig_service.errors import InvalidInput
from softsig_service.objects.cloud import MAX_POINTS, MIN_POINTS
from softsig_service.objects.schema import WORLD_FRAME

MESH_SUFFIXES: tuple[str, ...] = (".stl", ".obj", ".ply")
CLOUD_SUFFIXES: tuple[str, ...] = (".pcd", ".ply")
SUFFIXES: tuple[str, ...] = tuple(sorted({*MESH_SUFFIXES, *CLOUD_SUFFIXES}))
MAX_VERTICES = 100_000
"""Most vertices of a mesh object (the schema's limit)."""
MAX_FACES = 200_000
"""Most faces of a mesh object (the schema's limit)."""


def object_from_file(
    data: bytes,
    filename: str,
    *,
    mass: float,
    scale: float = 1.0,
    frame_id: str = WORLD_FRAME,
    kind: str | None = None,
    field: str = "file",
) -> dict[str, Any]:
    """The object JSON of the file ``filename`` (its suffix chooses the reader) whose bytes are ``data``: a ``mesh``
    (vertices [m] times ``scale``, faces) or a ``points`` cloud in ``frame_id``; ``mass`` [kg]. ``kind``
    (``"mesh"`` or ``"points"``) says which the file must give: ``"points"`` takes a mesh's vertices as a cloud,
    ``"mesh"`` refuses a file without triangles; by default a file with triangles is a mesh."""
    if kind not in (None, "mesh", "points"):
        raise InvalidInput("an object file is read as a mesh or as points", field="kind", value=kind,
                           choices=("mesh", "points"))  # fmt: skip
    suffix = PurePath(filename).suffix.lower()
    if suffix not in SUFFIXES:
        raise InvalidInput("unknown object file type", field=field, value=filename, choices=SUFFIXES)
    if not data:
        raise InvalidInput("the file is empty", field=field, value=filename)
    if not (np.isfinite(scale) and scale > 0.0):
        raise InvalidInput("scale must be a positive number", field="scale", value=scale)
    name = PurePath(filename).stem[:64]
    if suffix == ".pcd":
        points = _pcd_points(data, field, filename)
    else:
        geometry = _trimesh_load(data, suffix[1:], field, filename)
        faces = getattr(geometry, "faces", None)
        has_faces = faces is not None and len(faces) > 0
        if has_faces and kind != "points":
            return _mesh_json(np.asarray(geometry.vertices) * scale, np.asarray(faces), mass, name, field)
        points = np.asarray(getattr(geometry, "vertices", np.zeros((0, 3))), dtype=np.float64)
        if not has_faces and suffix != ".ply":
            raise InvalidInput(f"the file holds no triangles (or is no {suffix[1:].upper()} file)", field=field,
                               value=filename)  # fmt: skip
    if kind == "mesh":
        raise InvalidInput("the file holds no triangles: a cloud (kind points)", field=field, value=filename)
    points = points[np.all(np.isfinite(points), axis=1)] * scale
    if not MIN_POINTS <= len(points) <= MAX_POINTS:
        raise InvalidInput(
            f"a cloud has {MIN_POINTS} to {MAX_POINTS} finite points; the file has {len(points)}", field=field,
            value=filename,
        )  # fmt: skip
    return {"kind": "points", "points": points.tolist(), "frame_id": frame_id, "mass": mass, "name": name}


def _trimesh_load(data: bytes, file_type: str, field: str, filename: str) -> Any:
    import trimesh

    try:
        loaded = trimesh.load(io.BytesIO(data), file_type=file_type)
    except Exception as exc:  # the readers raise many kinds for malformed files
        raise InvalidInput(f"the {file_type.upper()} file does not parse: {exc}", field=field, value=filename) from None
    if isinstance(loaded, trimesh.Scene):  # several solids (a CAD export): one mesh of them all
        meshes = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
        return trimesh.util.concatenate(meshes) if meshes else trimesh.PointCloud(np.zeros((0, 3)))
    return loaded


def _pcd_points(data: bytes, field: str, filename: str) -> np.ndarray:
    from pypcd4 import PointCloud

    try:
        cloud = PointCloud.from_fileobj(io.BytesIO(data))  # type: ignore[arg-type]  # any binary stream
        if not {"x", "y", "z"} <= set(cloud.fields):
            raise InvalidInput("a PCD cloud needs the fields x, y and z", field=field, value=list(cloud.fields))
        return np.asarray(cloud.numpy(("x", "y", "z")), dtype=np.float64)
    except InvalidInput:
        raise
    except Exception as exc:
        raise InvalidInput(f"the PCD file does not parse: {exc}", field=field, value=filename) from None


def _mesh_json(vertices: np.ndarray, faces: np.ndarray, mass: float, name: str, field: str) -> dict[str, Any]:
    if len(vertices) > MAX_VERTICES or len(faces) > MAX_FACES:
        raise InvalidInput(
            f"a mesh object has at most {MAX_VERTICES} vertices and {MAX_FACES} faces; the file has "
            f"{len(vertices)} and {len(faces)}",
            field=field,
        )
    return {"kind": "mesh", "vertices": vertices.tolist(), "faces": faces.tolist(), "mass": mass, "name": name}
