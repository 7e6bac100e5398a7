"""The UR5's forward kinematics as a CasADi expression, generated from its Pinocchio model (the same URDF): for the
wrist-pose NLP over joint angles (:mod:`softsig_service.planning.wrist_nlp`).

The flange pose ``T_world_tool0(q)`` (4x4) is the product, joint by joint, of the model's constant joint placement
and the joint's rotation about its axis (revolute joints about x, y or z of their frame, or an unaligned axis), then
the flange frame's placement on its joint. Units: [m], [rad].
"""

from __future__ import annotations

import functools
from typing import Any

import casadi as ca
import numpy as np

from softsig_service.arm.ur5 import UR5


def _rotation(axis: np.ndarray, angle: Any) -> Any:
    """Rodrigues' rotation about the unit ``axis`` by the symbol ``angle``."""
    x, y, z = (float(v) for v in axis)
    c, s = ca.cos(angle), ca.sin(angle)
    C = 1 - c
    return ca.vertcat(
        ca.horzcat(c + x * x * C, x * y * C - z * s, x * z * C + y * s),
        ca.horzcat(y * x * C + z * s, c + y * y * C, y * z * C - x * s),
        ca.horzcat(z * x * C - y * s, z * y * C + x * s, c + z * z * C),
    )


def _joint_axis(joint: Any) -> np.ndarray:
    name = joint.shortname()
    for suffix, axis in (("RX", (1.0, 0.0, 0.0)), ("RY", (0.0, 1.0, 0.0)), ("RZ", (0.0, 0.0, 1.0))):
        if name.endswith(suffix):
            return np.array(axis)
    if "RevoluteUnaligned" in name:
        return np.asarray(joint.axis, dtype=np.float64)
    raise ValueError(f"the symbolic FK handles revolute joints only, not {name}")


def _homogeneous(R: Any, p: Any) -> Any:
    return ca.vertcat(ca.horzcat(R, p), ca.horzcat(ca.DM.zeros(1, 3), ca.DM.ones(1, 1)))


def symbolic_fk(ur5: UR5) -> ca.Function:
    """``fk(q) -> T_world_tool0`` (6 -> 4x4) of ``ur5``'s Pinocchio model as a CasADi function (cached per model)."""
    return _fk(id(ur5.model), ur5)


@functools.lru_cache(maxsize=4)
def _fk(_key: int, ur5: UR5) -> ca.Function:
    model = ur5.model
    q = ca.SX.sym("q", model.nq)
    placements: list[Any] = [ca.SX.eye(4)]
    for j in range(1, model.njoints):
        M = model.jointPlacements[j]
        local = _homogeneous(ca.DM(M.rotation), ca.DM(M.translation))
        turn = _homogeneous(_rotation(_joint_axis(model.joints[j]), q[model.idx_qs[j]]), ca.DM.zeros(3, 1))
        placements.append(placements[model.parents[j]] @ local @ turn)
    frame = model.frames[ur5.flange_frame_id]
    parent = frame.parentJoint if hasattr(frame, "parentJoint") else frame.parent
    F = frame.placement
    T = placements[parent] @ _homogeneous(ca.DM(F.rotation), ca.DM(F.translation))
    return ca.Function("ur5_fk", [q], [T])
