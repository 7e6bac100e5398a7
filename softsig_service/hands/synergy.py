"""The synergy closure (``closure.kind = "synergy"``): one scalar s in [0, 1] drives the coupled joints.

``q_j(s) = multiplier_j * s + offset_j`` [rad] or [m], clipped to the joint's limits (see
:class:`~softsig_service.hands.manifest.SynergyClosure` for the two realisations). Both are linear in s in their
controls, so the closure ramp of :mod:`softsig_service.hands.closure` (controls interpolated from open to
closed) is the synergy ramp:

* kinematic: one position servo ``softsig_synergy_<joint>`` per coupled joint, control ``multiplier * s +
  offset``, its control range the joint's range (MuJoCo clamps the control: that is the clipping);
* adaptive: a fixed tendon ``softsig_synergy`` with ``coef = multiplier_j``, and a force actuator
  ``softsig_synergy`` on it, control = tendon force ``stiffness * s`` [N·m]. Joint springs of ``stiffness`` about
  ``springref = offset_j`` balance it at ``q_j = offset_j + multiplier_j * s`` in free space (the same idea as
  the built-in SoftHand's tendon, whose free closure is its kinematic synergy). The force does not depend on
  where the joints are, so a blocked joint leaves the others as they are in free space. The actuator is a force
  source (stiffness 0 in the stiffness signature's ``Kz``).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import FrameNotFound, InvalidHandModel
from softsig_service.hands.manifest import SynergyClosure
from softsig_service.hands.mimic import Coupling

PREFIX = "softsig_synergy"


def synergy_couplings(closure: SynergyClosure, mimics: dict[str, Coupling]) -> list[Coupling]:
    """The joints s drives, each as ``q = multiplier * s + offset`` (root ``"s"``)."""
    if closure.multipliers is not None:
        return [Coupling(j, "s", m, closure.offsets.get(j, 0.0)) for j, m in closure.multipliers.items()]
    joint = closure.synergy_joint
    coupled = [Coupling(joint or "", "s", 1.0, 0.0)]
    coupled += [Coupling(c.joint, "s", c.multiplier, c.offset) for c in mimics.values() if c.root == joint]
    if len(coupled) == 1:
        raise InvalidHandModel(
            "no joint of the description mimics the synergy joint (a URDF <mimic joint=...> tag is needed)",
            field="closure.synergy_joint",
            value=joint,
            choices=sorted({c.root for c in mimics.values()}),
        )
    return coupled


def add_synergy(spec: mujoco.MjSpec, closure: SynergyClosure, coupled: list[Coupling]) -> None:
    """Add the closure's realisation (servos, or tendon and force actuator) and joint settings to ``spec``."""
    names = {j.name for j in spec.joints}
    for c in coupled:
        if c.joint not in names:
            field = "closure.synergy_joint" if closure.synergy_joint else f"closure.multipliers.{c.joint}"
            raise FrameNotFound("the synergy names a joint the model does not have", field=field, value=c.joint,
                                choices=names)  # fmt: skip
        joint = spec.joint(c.joint)
        joint.damping = [closure.damping, 0.0, 0.0]  # MuJoCo 4: polynomial damping (linear term only)
        joint.armature = closure.armature
    if closure.realisation == "kinematic":
        for c in coupled:
            joint = spec.joint(c.joint)
            act = spec.add_actuator(name=f"{PREFIX}_{c.joint}", target=c.joint)
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            act.set_to_position(kp=closure.kp, kv=closure.kv)
            if joint.limited != mujoco.mjtLimited.mjLIMITED_FALSE and joint.range[0] < joint.range[1]:
                act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
                act.ctrlrange = [float(joint.range[0]), float(joint.range[1])]
            if closure.force_limit is not None:
                act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
                act.forcerange = [-closure.force_limit, closure.force_limit]
        return
    tendon = spec.add_tendon(name=PREFIX)
    for c in coupled:
        joint = spec.joint(c.joint)
        joint.stiffness = [closure.stiffness, 0.0, 0.0]  # MuJoCo 4: polynomial spring (linear term only)
        joint.springref = c.offset
        tendon.wrap_joint(c.joint, c.multiplier)
    act = spec.add_actuator(name=PREFIX, target=PREFIX)
    act.trntype = mujoco.mjtTrn.mjTRN_TENDON
    act.gainprm[0] = 1.0
    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    act.ctrlrange = [0.0, closure.stiffness]


def synergy_controls(
    closure: SynergyClosure, coupled: list[Coupling], model: mujoco.MjModel
) -> tuple[tuple[int, ...], NDArray[np.float64], NDArray[np.float64], tuple[tuple[int, float], ...]]:
    """Actuator ids, their open and closed controls, and the open posture (qpos address, value)."""

    def at(s: float) -> NDArray[np.float64]:
        return np.array([c.multiplier * s + c.offset for c in coupled])

    posture = []
    for c, q in zip(coupled, at(closure.open), strict=True):
        j = model.joint(c.joint)
        lo, hi = model.jnt_range[j.id] if model.jnt_limited[j.id] else (-np.inf, np.inf)
        posture.append((int(j.qposadr[0]), float(np.clip(q, lo, hi))))
    if closure.realisation == "kinematic":
        ids = tuple(int(model.actuator(f"{PREFIX}_{c.joint}").id) for c in coupled)
        return ids, at(closure.open), at(closure.closed), tuple(posture)
    ids = (int(model.actuator(PREFIX).id),)
    force = closure.stiffness
    return ids, np.array([force * closure.open]), np.array([force * closure.closed]), tuple(posture)


def synergy_targets(coupled: Sequence[Coupling], model: mujoco.MjModel, s: float) -> dict[str, float]:
    """The kinematic synergy at ``s``: each coupled joint's ``multiplier * s + offset`` clipped to its limits."""
    out = {}
    for c in coupled:
        j = model.joint(c.joint).id
        q = c.multiplier * s + c.offset
        if model.jnt_limited[j]:
            q = float(np.clip(q, *model.jnt_range[j]))
        out[c.joint] = q
    return out
