"""Summaries of hands for people and for JSON: model statistics and what a closure does to the fingertips."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.hands.model import HandModel
from softsig_service.hands.mount_pose import hand_frame_axes
from softsig_service.hands.trajectory import ClosureTrajectory


def fingertip_spread(positions: NDArray[np.float64], names: tuple[str, ...]) -> float:
    """Mean distance [m] of the fingertip points (names ending in ``_tip``) to their centroid.

    Falls back to all points when no name ends in ``_tip``. This is the convergence measure of a closure.
    """
    idx = [k for k, n in enumerate(names) if n.endswith("_tip")] or list(range(len(names)))
    tips = positions[idx]
    return float(np.linalg.norm(tips - tips.mean(axis=0), axis=1).mean())


def hand_info(hand: HandModel) -> dict[str, Any]:
    """Static facts of a hand: manifest fields, model statistics, its reference points, the hand frame in the
    mount body's frame (``hand_frame``: origin [m] and unit axes), the URDF's mimic couplings, the joints a
    synergy closure drives, the self-collision pairs left unchecked (``excluded_pairs``: body1, body2, reason
    and detail; :mod:`softsig_service.hands.self_collision`), and for a xacro model the SHA-256 of its expanded
    URDF."""
    m = hand.model
    man = hand.manifest
    joint_types = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}
    return {
        "name": man.name,
        "description": man.description,
        "kind": man.kind,
        "model_file": man.model,
        "model_format": man.model_format,
        "folder": str(hand.folder),
        "mount": man.mount,
        "frame_id": "hand",
        "bodies": int(m.nbody - 1),
        "joints": [{"name": m.joint(j).name, "type": joint_types[int(m.jnt_type[j])]} for j in range(m.njnt)],
        "actuators": [m.actuator(a).name for a in range(m.nu)],
        "tendons": [m.tendon(t).name for t in range(m.ntendon)],
        "mass": float(sum(m.body_mass[1:])),
        "reference_points": [
            {
                "name": p.name,
                "kind": p.kind,
                "target": mujoco.mj_id2name(
                    m, mujoco.mjtObj.mjOBJ_SITE if p.kind == "site" else mujoco.mjtObj.mjOBJ_BODY, p.id
                ),
                "offset": list(p.offset),
            }
            for p in hand.points
        ],
        "hand_frame": hand_frame_axes(hand.hand_frame, man.mount),
        "mimics": [
            {"joint": c.joint, "root": c.root, "multiplier": c.multiplier, "offset": c.offset} for c in hand.mimics
        ],
        "synergy": [{"joint": c.joint, "multiplier": c.multiplier, "offset": c.offset} for c in hand.synergy],
        "excluded_pairs": [
            {"body1": p.body1, "body2": p.body2, "reason": p.reason, "detail": p.detail} for p in hand.excluded
        ],
        "expanded_urdf": None
        if hand.expanded is None
        else {
            "sha256": hand.expanded.sha256,
            "bytes": len(hand.expanded.xml.encode()),
            "files": list(hand.expanded.files),
        },
        "closure": man.closure.model_dump(),
        "simulation": man.simulation.model_dump(),
        "physical": man.physical.model_dump(),
    }


def closure_summary(traj: ClosureTrajectory) -> dict[str, Any]:
    """Open and closed fingertip spread [m], its ratio, and the largest point displacement [m]."""
    open_spread = fingertip_spread(traj.positions[0], traj.point_names)
    closed_spread = fingertip_spread(traj.positions[-1], traj.point_names)
    disp = np.linalg.norm(traj.positions[-1] - traj.positions[0], axis=1)
    return {
        "hand": traj.hand,
        "frames": traj.n_frames,
        "duration": float(traj.times[-1]),
        "points": traj.n_points,
        "spread_open": open_spread,
        "spread_closed": closed_spread,
        "spread_ratio": closed_spread / open_spread if open_spread > 0 else float("nan"),
        "max_displacement": float(disp.max()),
    }
