"""A ranked grasp as the JSON of ``moveit_msgs/msg/Grasp`` (ROS 2 field names and types; the message's own
nesting: ``trajectory_msgs/JointTrajectory``, ``geometry_msgs/PoseStamped``, ``moveit_msgs/GripperTranslation``
with ``geometry_msgs/Vector3Stamped``, ``builtin_interfaces/Duration`` as ``{sec, nanosec}``).

- ``grasp_pose`` is the pose of the link the hand mounts on (the UR5 flange ``tool0``), in the answer's frame.
- ``pre_grasp_posture`` / ``grasp_posture``: the hand's closure commands at their open values (at time 0) and at
  their closed values (at the closure's duration [s]); positions only, in the commands' own units. A command is the
  joint a posture closure servos (its name in the hand's description), else the closure actuator (a motor or a
  tendon's force source, e.g. the SoftHand's ``synergy``).
- ``pre_grasp_approach``: along the approach (the hand's +z) for the plan's approach distance [m], at least half
  of it; ``post_grasp_retreat``: straight up (``base_link`` +z) by the validation's lift, at least half of it;
  ``post_place_retreat``: back along the approach by the approach distance.
- ``max_contact_force`` 0 (no limit: MoveIt's "<= 0 to disable"); ``allowed_touch_objects`` empty (the planner
  keeps every obstacle clear).
Stamps are zero (``{sec: 0, nanosec: 0}``): the answer is not tied to a time; a stack stamps it when it sends it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from softsig_service.geometry.quaternions import rotation_to_quat
from softsig_service.geometry.transforms import unit_quat_to_wire

ZERO_TIME = {"sec": 0, "nanosec": 0}


def duration(seconds: float) -> dict[str, int]:
    """``builtin_interfaces/Duration`` of ``seconds`` (>= 0), rounded to the nanosecond."""
    ns = round(max(0.0, float(seconds)) * 1e9)
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def header(frame_id: str) -> dict[str, Any]:
    """``std_msgs/Header`` with a zero stamp."""
    return {"stamp": dict(ZERO_TIME), "frame_id": frame_id}


def joint_trajectory(
    joint_names: Sequence[str],
    positions: Sequence[Sequence[float]],
    times: Sequence[float],
    velocities: Sequence[Sequence[float]] | None = None,
    frame_id: str = "",
) -> dict[str, Any]:
    """``trajectory_msgs/JointTrajectory``: one point per row of ``positions`` at ``times`` [s] from the start,
    with ``velocities`` when given (accelerations and efforts left empty)."""
    points = []
    for k, (q, t) in enumerate(zip(positions, times, strict=True)):
        points.append({
            "positions": [float(v) for v in q],
            "velocities": [float(v) for v in velocities[k]] if velocities is not None else [],
            "accelerations": [],
            "effort": [],
            "time_from_start": duration(t),
        })  # fmt: skip
    return {"header": header(frame_id), "joint_names": list(joint_names), "points": points}


def _vector(v: NDArray[np.float64]) -> dict[str, float]:
    return {"x": float(v[0]), "y": float(v[1]), "z": float(v[2])}


def gripper_translation(
    direction: NDArray[np.float64], frame_id: str, desired: float, minimum: float
) -> dict[str, Any]:
    """``moveit_msgs/GripperTranslation``: a unit ``direction`` in ``frame_id`` and the distances [m]."""
    d = np.asarray(direction, dtype=np.float64)
    n = float(np.linalg.norm(d))
    return {
        "direction": {"header": header(frame_id), "vector": _vector(d / n if n > 0 else d)},
        "desired_distance": float(desired),
        "min_distance": float(minimum),
    }


def pose_stamped(T: NDArray[np.float64], frame_id: str) -> dict[str, Any]:
    """``geometry_msgs/PoseStamped`` of the 4x4 pose ``T`` in ``frame_id``."""
    return {
        "header": header(frame_id),
        "pose": {"position": _vector(T[:3, 3]), "orientation": unit_quat_to_wire(rotation_to_quat(T[:3, :3]))},
    }


def moveit_grasp(
    grasp_id: str,
    T_grasp: NDArray[np.float64],
    frame_id: str,
    quality: float,
    closure: Mapping[str, Any],
    approach_direction: NDArray[np.float64],
    approach_distance: float,
    retreat_direction: NDArray[np.float64],
    retreat_distance: float,
) -> dict[str, Any]:
    """The ``moveit_msgs/Grasp`` JSON (module docstring) of a grasp: the flange pose ``T_grasp`` (4x4) and the
    directions (unit, in ``frame_id``), distances [m], ``quality`` in [0, 1], ``closure`` the plan's closure
    command (``actuators``, ``open``, ``closed``, ``duration`` [s])."""
    if not math.isfinite(quality):
        quality = 0.0
    actuators = list(closure.get("commands") or closure["actuators"])
    approach = gripper_translation(approach_direction, frame_id, approach_distance, 0.5 * approach_distance)
    retreat = gripper_translation(retreat_direction, frame_id, retreat_distance, 0.5 * retreat_distance)
    place_retreat = gripper_translation(
        -np.asarray(approach_direction), frame_id, approach_distance, 0.5 * approach_distance
    )
    return {
        "id": grasp_id,
        "pre_grasp_posture": joint_trajectory(actuators, [closure["open"]], [0.0]),
        "grasp_posture": joint_trajectory(actuators, [closure["closed"]], [float(closure["duration"])]),
        "grasp_pose": pose_stamped(T_grasp, frame_id),
        "grasp_quality": float(quality),
        "pre_grasp_approach": approach,
        "post_grasp_retreat": retreat,
        "post_place_retreat": place_retreat,
        "max_contact_force": 0.0,
        "allowed_touch_objects": [],
    }
