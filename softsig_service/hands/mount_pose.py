"""The manifest's ``mount_pose``: where the hand frame (docs/design.md §3) sits in a description's own mount body.

A description's base link rarely follows softsig's hand frame (origin at the flange, +z out of the palm toward
the object, +x across the palm). ``mount_pose = { xyz = [..], rpy = [..] }`` (or ``quaternion = { x, y, z, w }``)
gives the hand frame's pose in the mount body's frame, ``T_MH``: its origin ``xyz`` [m] and orientation (URDF
roll-pitch-yaw [rad], ``R = Rz(yaw) Ry(pitch) Rx(roll)``, or a unit quaternion). Loading applies it without
editing the description: every element the mount body holds directly (child bodies, geoms, sites, cameras,
lights, frames, and an explicit inertial) is moved into one MJCF frame with the pose ``T_HM = T_MH^-1``, so the
mount body's frame becomes the hand frame and every name stays as the description wrote it.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.geometry.quaternions import matrix_to_quat, quat_from_wire, quat_to_matrix, quat_to_wire
from softsig_service.geometry.transforms import invert, make_transform, rpy_to_matrix
from softsig_service.hands.manifest import MountPose

_CHILD_KINDS = ("bodies", "geoms", "sites", "cameras", "lights", "frames")


def mount_transform(pose: MountPose | None) -> NDArray[np.float64]:
    """``T_MH`` (4x4): the hand frame in the mount body's frame; the identity when no pose is given."""
    if pose is None:
        return np.eye(4)
    if pose.quaternion is not None:
        R = quat_to_matrix(quat_from_wire(pose.quaternion, field="mount_pose.quaternion"))
    else:
        R = rpy_to_matrix(*(pose.rpy or (0.0, 0.0, 0.0)))
    return make_transform(R, pose.xyz)


def apply_mount_pose(spec: mujoco.MjSpec, mount: str, T_MH: NDArray[np.float64]) -> None:
    """Re-express everything the body ``mount`` holds so that its frame becomes the hand frame ``T_MH``."""
    if np.allclose(T_MH, np.eye(4)):
        return
    body = spec.body(mount)
    if body is None:
        return  # compile_hand reports the missing mount body with the model's names
    T_HM = invert(T_MH)
    q_HM = matrix_to_quat(T_HM[:3, :3])
    children = [e for kind in _CHILD_KINDS for e in getattr(body, kind) if e.frame is None]
    frame = body.add_frame(pos=T_HM[:3, 3].tolist(), quat=q_HM.tolist())
    frame.name = "softsig_hand_frame"
    for element in children:
        element.set_frame(frame)
    if body.explicitinertial:
        body.ipos = (T_HM[:3, :3] @ np.asarray(body.ipos) + T_HM[:3, 3]).tolist()
        body.iquat = matrix_to_quat(T_HM[:3, :3] @ quat_to_matrix(np.asarray(body.iquat))).tolist()


def hand_frame_axes(T_MH: NDArray[np.float64], mount: str) -> dict[str, Any]:
    """The hand frame as a person checks it: origin [m] and unit axes x, y, z in the mount body's frame."""
    R = T_MH[:3, :3]
    return {
        "relative_to": mount,
        "origin": [float(v) for v in T_MH[:3, 3]],
        "x": [float(v) for v in R[:, 0]],
        "y": [float(v) for v in R[:, 1]],
        "z": [float(v) for v in R[:, 2]],
        "quaternion": quat_to_wire(matrix_to_quat(R)),
    }
