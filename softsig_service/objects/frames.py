"""The frames of a request: poses of named frames in ``base_link``, as a robot stack's tf gives them, and geometry
brought from one of them into ``base_link``.

A request names the frame its geometry is in (``frame_id``; default ``base_link``) and gives the pose of every other
frame it names (``frames: {"camera_color_optical_frame": {"position": {x, y, z}, "orientation": {x, y, z, w}}}``,
geometry_msgs order; REP 103/105 names). A quaternion within 1e-3 of unit length is normalised; one further off
is refused (it is not a rotation a tf would give). Pure numpy.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput
from softsig_service.geometry.transforms import transform_from_quat
from softsig_service.objects.schema import WORLD_FRAME

FloatArray = NDArray[np.float64]

UNIT_TOLERANCE = 1e-3
"""How far from 1 a frame's quaternion norm may be before it is refused."""

Frames = Mapping[str, FloatArray]
"""Frame name -> ``T_base_link_frame`` (4x4)."""


def unit_quaternion(q: Mapping[str, float], field: str) -> FloatArray:
    """The quaternion ``q`` (``{"x", "y", "z", "w"}``) as a unit wxyz array, normalised when its norm is within
    :data:`UNIT_TOLERANCE` of 1; :class:`InvalidInput` naming ``field`` otherwise."""
    q_wxyz = np.array([q["w"], q["x"], q["y"], q["z"]], dtype=np.float64)
    norm = float(np.linalg.norm(q_wxyz))
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise InvalidInput(f"the orientation is not a unit quaternion (norm {norm:.6g})", field=field,
                           value=[q["x"], q["y"], q["z"], q["w"]])  # fmt: skip
    return q_wxyz / norm


def frame_transforms(frames: Mapping[str, Mapping[str, Any]] | None, field: str = "frames") -> dict[str, FloatArray]:
    """The 4x4 poses in ``base_link`` of ``frames`` (name -> ``{"position", "orientation"}`` JSON). Raises
    :class:`InvalidInput` naming ``frames.<name>.orientation`` for a quaternion that is not (nearly) unit, and
    refuses a pose given for ``base_link`` itself."""
    out: dict[str, FloatArray] = {}
    for name, pose in (frames or {}).items():
        if name == WORLD_FRAME:
            raise InvalidInput(f"{WORLD_FRAME} is the world frame: its pose is not given", field=f"{field}.{name}")
        p = pose["position"]
        q = unit_quaternion(pose["orientation"], f"{field}.{name}.orientation")
        out[name] = transform_from_quat([p["x"], p["y"], p["z"]], q)
    return out


def to_world(points: FloatArray, frame_id: str, frames: Frames | None, field: str) -> FloatArray:
    """``points`` ``(N, 3)`` [m] given in ``frame_id``, expressed in ``base_link``. Raises :class:`InvalidInput`
    naming ``field`` (the ``frame_id``'s path) with the known frames when ``frame_id`` is neither ``base_link`` nor
    one of ``frames``."""
    if frame_id == WORLD_FRAME:
        return points
    known = frames or {}
    if frame_id not in known:
        raise InvalidInput(
            "unknown frame: give its pose in base_link under frames", field=field, value=frame_id,
            choices=(WORLD_FRAME, *sorted(known)),
        )  # fmt: skip
    T = known[frame_id]
    return np.asarray(points @ T[:3, :3].T + T[:3, 3], dtype=np.float64)


UR_BASE_FRAME = "base"
"""The UR controller's base frame (the teach pendant's, URScript's): ``base_link`` turned by pi about z, as the
ROS descriptions of the UR arms define it (x and y of the two frames point opposite ways)."""
OBJECT_FRAME = "object"
"""The planned object's own frame (its pose in ``base_link``: centre, principal axes)."""
T_BASE_LINK_UR_BASE: FloatArray = np.diag([-1.0, -1.0, 1.0, 1.0])
"""``T_base_link_base``: a half turn about z."""


def output_frame_pose(
    name: str, frames: Frames | None, object_pose: FloatArray, field: str = "output_frame"
) -> FloatArray:
    """``T_base_link_frame`` (4x4) of the frame an answer is expressed in: ``base_link``, the UR controller's
    ``base``, the ``object``'s frame (its pose ``object_pose``) or one of the request's ``frames``. Raises
    :class:`InvalidInput` naming ``field`` with the choices for another name."""
    if name == WORLD_FRAME:
        return np.eye(4)
    if name == UR_BASE_FRAME:
        return T_BASE_LINK_UR_BASE.copy()
    if name == OBJECT_FRAME:
        return np.asarray(object_pose, dtype=np.float64).copy()
    known = frames or {}
    if name not in known:
        raise InvalidInput("unknown output frame: base_link, base, object or a frame of the request's frames",
                           field=field, value=name, choices=(WORLD_FRAME, UR_BASE_FRAME, OBJECT_FRAME,
                                                             *sorted(known)))  # fmt: skip
    return np.asarray(known[name], dtype=np.float64).copy()
