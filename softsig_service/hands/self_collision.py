"""Self-collision pairs a hand does not check, as ROS tools leave them out.

ROS never checks some pairs of a robot's links: links adjacent in the description, and the pairs MoveIt's setup
assistant writes to an SRDF's ``<disable_collisions>`` (among them the pairs in collision at the default pose).
Collision meshes of neighbouring links often overlap (the official Pisa/IIT SoftHand description's do), and a
simulator that checks them pushes the fingers apart. On load softsig excludes (``MjSpec.add_exclude``), once per
hand:

* ``adjacent``, for a URDF or xacro description: two links joined by a joint, where links joined by a ``fixed``
  joint count as one rigid link (as MuJoCo welds them) and a link without collision geometry (a virtual link of
  a joint chain) joins its neighbours. Only links with collision geometry are paired.
* ``srdf``: every ``<disable_collisions link1= link2=>`` of the ``*.srdf`` files in the hand's folder whose two
  links are bodies of the model.
* ``contact at open pose``: hand bodies whose geoms penetrate at the open posture (MoveIt's "default" category).

Pairs that meet only during the closure stay checked: a thumb pressing the index is physics.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Literal

import mujoco

from softsig_service.config import ModelLimits
from softsig_service.errors import InvalidHandModel
from softsig_service.hands.assets import inside, read_limited
from softsig_service.hands.xacro_expand import CACHE_DIR

Reason = Literal["adjacent", "srdf", "contact at open pose"]


@dataclass(frozen=True)
class ExcludedPair:
    """Two bodies (URDF links) whose contacts are not checked, and why."""

    body1: str
    body2: str
    reason: Reason
    detail: str = ""
    """What the reason rests on: the joints between adjacent links (from ``body1``), the SRDF file and its reason,
    or the deepest penetration at the open pose."""


def _key(a: str, b: str) -> tuple[str, str]:
    return (a, b) if a <= b else (b, a)


def urdf_adjacent_pairs(urdf_xml: str) -> list[tuple[str, str, str]]:
    """Pairs of links with collision geometry that are adjacent (module docstring), sorted, each with the joints
    that join them; links joined by fixed joints are one rigid link, links without collision geometry are passed
    through."""
    root = ET.fromstring(urdf_xml)
    links = {el.get("name", ""): el.find("collision") is not None for el in root.findall("link")}
    group = {name: name for name in links}

    def find(name: str) -> str:
        while group[name] != name:
            group[name] = group[group[name]]
            name = group[name]
        return name

    moving: list[tuple[str, str, str]] = []
    for joint in root.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None:
            continue
        a, b = parent.get("link", ""), child.get("link", "")
        if a not in links or b not in links:
            continue
        if joint.get("type") == "fixed":
            group[find(b)] = find(a)
        else:
            moving.append((a, b, joint.get("name", "")))
    members: dict[str, list[str]] = {}
    for name in links:
        members.setdefault(find(name), []).append(name)
    solid = {g for g, names in members.items() if any(links[n] for n in names)}
    edges: dict[str, list[tuple[str, str]]] = {g: [] for g in members}
    for a, b, via_joint in moving:
        ga, gb = find(a), find(b)
        if ga != gb:
            edges[ga].append((gb, via_joint))
            edges[gb].append((ga, via_joint))
    out: dict[tuple[str, str], str] = {}
    for start in sorted(solid):
        stack, seen = [(start, "")], {start}
        while stack:
            at, path = stack.pop()
            for nxt, via_joint in edges[at]:
                if nxt in seen:
                    continue
                seen.add(nxt)
                via = f"{path} {via_joint}".strip()
                if nxt in solid:
                    for x in members[start]:
                        for y in members[nxt]:
                            if links[x] and links[y]:  # the joints listed from the first link of the pair
                                out.setdefault(_key(x, y), via if x < y else " ".join(reversed(via.split())))
                else:
                    stack.append((nxt, via))
    return sorted((a, b, via) for (a, b), via in out.items())


def srdf_disabled_pairs(srdf_xml: str, field: str = "srdf") -> list[tuple[str, str, str]]:
    """The ``<disable_collisions link1= link2= reason=>`` pairs of an SRDF (link1, link2, its reason)."""
    try:
        root = ET.fromstring(srdf_xml)
    except ET.ParseError as exc:
        raise InvalidHandModel(f"the SRDF is not well-formed XML: {exc}", field=field) from None
    out = []
    for el in root.findall("disable_collisions"):
        a, b = el.get("link1"), el.get("link2")
        if not a or not b:
            raise InvalidHandModel("disable_collisions needs link1 and link2", field=field, value=dict(el.attrib))
        out.append((a, b, el.get("reason", "")))
    return out


def srdf_files(folder: Path) -> list[Path]:
    """The ``*.srdf`` files of a hand's folder (not its cache), sorted."""
    root = folder.resolve()
    return sorted(p for p in root.rglob("*.srdf") if p.is_file() and p.relative_to(root).parts[0] != CACHE_DIR)


def open_pose_contacts(model: mujoco.MjModel, posture: Iterable[tuple[int, float]]) -> dict[tuple[str, str], float]:
    """Pairs of bodies (not the world) whose geoms penetrate at ``posture`` (qpos address, value), with the
    deepest penetration [m]."""
    data = mujoco.MjData(model)
    for adr, value in posture:
        data.qpos[adr] = value
    mujoco.mj_forward(model, data)
    out: dict[tuple[str, str], float] = {}
    for c in data.contact[: data.ncon]:
        b1, b2 = int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])
        if c.dist >= 0.0 or b1 == 0 or b2 == 0 or b1 == b2:
            continue
        key = _key(model.body(b1).name, model.body(b2).name)
        out[key] = max(out.get(key, 0.0), -float(c.dist))
    return out


def excluded_pairs(
    model: mujoco.MjModel,
    posture: Iterable[tuple[int, float]],
    urdf_xml: str | None,
    folder: Path,
    limits: ModelLimits,
) -> tuple[ExcludedPair, ...]:
    """The pairs a hand does not check, each once with its first reason (adjacent, srdf, contact at open pose).

    ``model`` is the hand compiled without exclusions (nothing else in it), ``posture`` its open posture."""
    bodies = {model.body(b).name for b in range(1, model.nbody)}
    out: dict[tuple[str, str], ExcludedPair] = {}
    if urdf_xml is not None:
        for a, b, via in urdf_adjacent_pairs(urdf_xml):
            if a in bodies and b in bodies:
                out[_key(a, b)] = ExcludedPair(*_key(a, b), "adjacent", f"joints {via}")
    for path in srdf_files(folder):
        rel = path.relative_to(folder.resolve()).as_posix()
        text = read_limited(inside(folder, PurePosixPath(rel), "srdf", rel), limits.max_model_bytes, "srdf", rel)
        for a, b, why in srdf_disabled_pairs(text.decode("utf-8", "replace"), field=f"srdf: {rel}"):
            if a in bodies and b in bodies and a != b and _key(a, b) not in out:
                out[_key(a, b)] = ExcludedPair(*_key(a, b), "srdf", f"{rel} ({why})" if why else rel)
    for key, depth in open_pose_contacts(model, posture).items():
        if key not in out:
            out[key] = ExcludedPair(*key, "contact at open pose", f"penetration {depth * 1e3:.2f} mm")
    return tuple(out[k] for k in sorted(out))


def add_excludes(spec: mujoco.MjSpec, pairs: Iterable[ExcludedPair]) -> None:
    """One ``<exclude>`` per pair."""
    for pair in pairs:
        exclude = spec.add_exclude()
        exclude.bodyname1 = pair.body1
        exclude.bodyname2 = pair.body2
