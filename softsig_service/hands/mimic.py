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
    """Every mimic of a URDF, resolved to its root joint; keyed by the mimicking joint's name."""
    root = ET.fromstring(urdf_xml)
    joints = {j.get("name", ""): j for j in root.iter("joint")}
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


def add_mimic_equalities(spec: mujoco.MjSpec, couplings: dict[str, Coupling], skip: set[str]) -> None:
    """One joint equality per coupling (except the joints in ``skip``, which a synergy closure drives)."""
    for c in couplings.values():
        if c.joint in skip:
            continue
        if spec.joint(c.joint) is None or spec.joint(c.root) is None:
            continue  # a fixed joint (no MuJoCo joint): nothing moves, nothing to couple
        eq = spec.add_equality(name=f"{EQUALITY_PREFIX}{c.joint}")
        eq.type = mujoco.mjtEq.mjEQ_JOINT
        eq.objtype = mujoco.mjtObj.mjOBJ_JOINT
        eq.name1 = c.joint
        eq.name2 = c.root
        eq.data[:5] = [c.offset, c.multiplier, 0.0, 0.0, 0.0]
