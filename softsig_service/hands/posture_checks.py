"""Checks of a posture closure against the compiled hand: every joint that a posture closure leaves without a drive,
and every target outside its joint's range, is refused before anything is simulated.

A posture closure adds a position servo to each joint its ``open`` and ``closed`` postures name
(:mod:`softsig_service.hands.model`). A hinge or slide joint of the hand that is not named, and that nothing else
drives (an actuator of the model, a joint equality such as a mimic coupling, a tendon), swings freely during the
closure. A target outside a limited joint's range is one the servo can never reach. Both are mistakes in the
manifest (the Allegro hand's ``joint_0.0`` left out; ``joint_12.0 = 0.0`` below its lower limit of 0.263 rad), so
:class:`InvalidHandModel` names the joint.
"""

from __future__ import annotations

import math

import mujoco

from softsig_service.errors import InvalidHandModel
from softsig_service.hands.manifest import PostureClosure

RANGE_TOLERANCE = 1e-6
"""[rad] or [m] a target may lie outside its joint's range (rounding in a manifest)."""


def driven_joints(model: mujoco.MjModel) -> set[int]:
    """Ids of the joints the model itself drives or couples: actuated (directly or through a tendon), or in a
    joint equality."""
    out: set[int] = set()
    for a in range(model.nu):
        kind, target = int(model.actuator_trntype[a]), int(model.actuator_trnid[a, 0])
        if kind == mujoco.mjtTrn.mjTRN_JOINT:
            out.add(target)
        elif kind == mujoco.mjtTrn.mjTRN_TENDON:
            adr, num = int(model.tendon_adr[target]), int(model.tendon_num[target])
            for w in range(adr, adr + num):
                if int(model.wrap_type[w]) == mujoco.mjtWrap.mjWRAP_JOINT:
                    out.add(int(model.wrap_objid[w]))
    for e in range(model.neq):
        if int(model.eq_type[e]) == mujoco.mjtEq.mjEQ_JOINT:
            out.update(int(j) for j in (model.eq_obj1id[e], model.eq_obj2id[e]) if j >= 0)
    return out


def check_posture(model: mujoco.MjModel, closure: PostureClosure) -> None:
    """Refuse (:class:`InvalidHandModel` naming ``closure.open``/``closure.closed`` and the joint) a posture closure
    that leaves a hinge or slide joint undriven or targets a joint outside its range; hinge targets [rad] must lie
    within [-2 pi, 2 pi] whether the joint is limited or not."""
    driven = driven_joints(model)
    named = {int(model.joint(j).id) for j in closure.open}
    for j in range(model.njnt):
        kind = int(model.jnt_type[j])
        if kind not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE) or j in named:
            continue
        if j not in driven:
            name = model.joint(j).name
            raise InvalidHandModel(
                f"the posture closure leaves joint {name!r} without a servo target: name it in both open and "
                "closed (or couple it to a named joint with a mimic tag)",
                field="closure.open",
                value=name,
            )
    for which, posture in (("open", closure.open), ("closed", closure.closed)):
        for name, target in posture.items():
            jid = int(model.joint(name).id)
            field = f"closure.{which}.{name}"
            if int(model.jnt_type[jid]) == mujoco.mjtJoint.mjJNT_HINGE and abs(target) > 2.0 * math.pi:
                raise InvalidHandModel(
                    f"a hinge target in radians within [-2 pi, 2 pi] (is {target:g} in degrees?)", field=field,
                    value=target,
                )  # fmt: skip
            if model.jnt_limited[jid]:
                lo, hi = (float(v) for v in model.jnt_range[jid])
                if not lo - RANGE_TOLERANCE <= target <= hi + RANGE_TOLERANCE:
                    raise InvalidHandModel(
                        f"target {target:g} is outside the joint's range [{lo:g}, {hi:g}]", field=field, value=target,
                        choices=[lo, hi],
                    )  # fmt: skip
