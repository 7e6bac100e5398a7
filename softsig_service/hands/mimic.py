"""URDF ``<mimic>`` tags as MuJoCo joint equalities.

``<joint name="B"><mimic joint="A" multiplier="m" offset="o"/></joint>`` states ``q_B = m q_A + o`` (URDF;
[rad] for revolute joints, [m] for prismatic ones; multiplier 1 and offset 0 when omitted). MuJoCo's URDF parser
of older versions ignores the tag and MuJoCo 4 couples to the direct target only; softsig removes the tags before
MuJoCo reads the URDF (:func:`strip_mimics`) and gives every such joint a joint equality
``joint1 = B, joint2 = ROOT, polycoef = (o', m', 0, 0, 0)`` where ROOT is the end of its chain of mimics (A,
or what A mimics, ...), with the chain's multipliers multiplied and offsets carried through:
``q_B = m_B (m_A q_R + o_A) + o_B``. A cycle of mimics or a mimic of a joint the description does not have is
an error that names the joint.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import mujoco

from softsig_service.errors import FrameNotFound, InvalidHandModel

EQUALITY_PREFIX = "softsig_mimic_"
MIMIC_ARMATURE = 1e-4
"""Armature [kg·m² or kg] given to every joint of a mimic coupling that has less (URDF has no armature). An
approximate value, the built-in SoftHand's: without it a light virtual synergy link (a few grams) driving the
fingers through the equalities is unstable at a 2 ms step."""


@dataclass(frozen=True)
class Coupling:
    """``joint = multiplier * root + offset`` (root and joint [rad] or [m]; offset in the joint's unit)."""

    joint: str
    root: str
    multiplier: float
    offset: float


def _number(el: ET.Element, attr: str, default: float, joint: str) -> float:
    text = el.get(attr)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not math.isfinite(value):
        raise InvalidHandModel(f"mimic {attr} must be a finite number", field=f"model: joint {joint} mimic", value=text)
    return value


def mimic_couplings(urdf_xml: str) -> dict[str, Coupling]:
    """Every mimic of a URDF, resolved to its root joint; keyed by the mimicking joint's name.

    Only the robot's own joints (``<joint>`` children of ``<robot>``) count: a ``<transmission>`` names joints
    with ``<joint name=...>`` elements of its own, which must not stand in for the real ones."""
    root = ET.fromstring(urdf_xml)
    joints = {j.get("name", ""): j for j in root.findall("joint")}
    direct: dict[str, Coupling] = {}
    for name, el in joints.items():
        tag = el.find("mimic")
        if tag is None:
            continue
        target = tag.get("joint", "")
        if target not in joints:
            raise FrameNotFound("mimic names a joint the description does not have", field=f"model: joint {name} mimic",
                                value=target, choices=sorted(joints))  # fmt: skip
        direct[name] = Coupling(name, target, _number(tag, "multiplier", 1.0, name), _number(tag, "offset", 0.0, name))
    for name in direct:
        seen, at = [name], direct[name].root
        while at in direct:
            if at in seen:
                raise InvalidHandModel("mimic tags form a cycle", field=f"model: joint {name} mimic", value=seen)
            seen.append(at)
            at = direct[at].root
    return {name: _compose(direct, name) for name in direct}


def _compose(direct: dict[str, Coupling], name: str) -> Coupling:
    """Follow ``name``'s chain to its root: q_name = m q_root + o."""
    chain = [direct[name]]
    while chain[-1].root in direct:
        chain.append(direct[chain[-1].root])
    m, o = 1.0, 0.0
    for step in reversed(chain):  # from the root outward: q_step = s.m * q_prev + s.o
        m, o = step.multiplier * m, step.multiplier * o + step.offset
    return Coupling(name, chain[-1].root, m, o)


def strip_mimics(urdf_xml: str) -> str:
    """The URDF without its ``<mimic>`` tags (softsig adds the couplings itself, resolved to their roots)."""
    root = ET.fromstring(urdf_xml)
    for joint in root.iter("joint"):
        for tag in joint.findall("mimic"):
            joint.remove(tag)
    return ET.tostring(root, encoding="unicode")


def add_mimic_equalities(spec: mujoco.MjSpec, couplings: dict[str, Coupling], skip: set[str], timestep: float) -> None:
    """One joint equality per coupling (except the joints in ``skip``, which a synergy closure drives).

    The equalities are stiffer than MuJoCo's default (time constant ``2 * timestep`` [s], the smallest MuJoCo
    advises, instead of 0.02 s; impedance 0.95..0.99) so that a coupling holds within about 1e-3 rad while the
    hand moves."""
    for c in couplings.values():
        if c.joint in skip:
            continue
        if spec.joint(c.joint) is None or spec.joint(c.root) is None:
            continue  # a fixed joint (no MuJoCo joint): nothing moves, nothing to couple
        for name in (c.joint, c.root):
            joint = spec.joint(name)
            joint.armature = max(float(joint.armature), MIMIC_ARMATURE)
        eq = spec.add_equality(name=f"{EQUALITY_PREFIX}{c.joint}")
        eq.type = mujoco.mjtEq.mjEQ_JOINT
        eq.objtype = mujoco.mjtObj.mjOBJ_JOINT
        eq.name1 = c.joint
        eq.name2 = c.root
        eq.data[:5] = [c.offset, c.multiplier, 0.0, 0.0, 0.0]
        eq.solref = [2.0 * timestep, 1.0]
        eq.solimp = [0.95, 0.99, 0.001, 0.5, 2.0]


def mimic_posture(
    model: mujoco.MjModel, couplings: dict[str, Coupling], posture: tuple[tuple[int, float], ...]
) -> tuple[tuple[int, float], ...]:
    """``posture`` (qpos address, value) completed with every mimic joint at ``multiplier * root + offset``
    (clipped to its limits), the root at its posture value or at 0: the open hand satisfies its couplings."""
    values = dict(posture)
    out = list(posture)
    for c in couplings.values():
        j, r = (
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, c.joint),
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, c.root),
        )
        if j < 0 or r < 0 or int(model.jnt_qposadr[j]) in values:
            continue
        q = c.multiplier * values.get(int(model.jnt_qposadr[r]), 0.0) + c.offset
        if model.jnt_limited[j]:
            q = min(max(q, float(model.jnt_range[j][0])), float(model.jnt_range[j][1]))
        out.append((int(model.jnt_qposadr[j]), q))
    return tuple(out)
