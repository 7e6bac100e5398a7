"""Why a trial ended as it did, in numbers: what the scene shows at the end of each phase of the rollout.

At the end of the approach, the closure, the lift and the hold (:func:`snapshot`): the hand bodies touching the
object with the normal force each presses on it [N] (MuJoCo's contact forces, ``mj_contactForce``, summed per hand
body; penetrating contacts only), whether the object touches the table, the height of its centre above the table top
[m] and its centre in the flange (``tool0``) frame [m]. A rollout also records the first moment [s] the object lost
every contact with the hand after the closure had it in contact (``released_at``). :func:`summary` turns a diagnosis
into one line a person reads ("closure ended with 2 contacts (thumb 0.0 N, index 3.1 N); ...").
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

import mujoco
import numpy as np

from softsig_service.simulation.scene_model import GEOM_HAND, GEOM_OBJECT, HAND_PREFIX, Scene

PHASES: tuple[str, ...] = ("approach", "closure", "lift", "hold")
"""The phases a rollout runs; a trial stopped early (``softsig_service.simulation.rollout.STOP_RULES``) ends its
diagnosis with a snapshot named ``stopped``."""
NO_FORCE = 0.05
"""[N] a hand body pressing less than this on the object is reported as touching without load."""


def object_contacts(scene: Scene, data: mujoco.MjData) -> Iterator[tuple[int, int, bool]]:
    """The penetrating contacts (distance <= 0) of an object geom with a geom of another class: (contact index,
    the other geom, whether the object's geom is the contact's ``geom1``)."""
    cls = scene.geom_class
    for i in range(data.ncon):
        con = data.contact[i]
        if con.dist > 0.0:
            continue
        g1, g2 = int(con.geom1), int(con.geom2)
        if cls[g1] == cls[g2] or GEOM_OBJECT not in (cls[g1], cls[g2]):
            continue
        yield (i, g2, True) if cls[g1] == GEOM_OBJECT else (i, g1, False)


def hand_forces(scene: Scene, data: mujoco.MjData) -> dict[str, float]:
    """Per hand body touching the object (penetrating contacts): the normal force it presses on the object [N]."""
    out: dict[str, float] = {}
    f6 = np.zeros(6)
    for i, hand_geom, _ in object_contacts(scene, data):
        if scene.geom_class[hand_geom] != GEOM_HAND:
            continue
        mujoco.mj_contactForce(scene.model, data, i, f6)
        name = scene.model.body(int(scene.model.geom_bodyid[hand_geom])).name.removeprefix(HAND_PREFIX)
        out[name] = out.get(name, 0.0) + abs(float(f6[0]))
    return {k: round(v, 4) for k, v in sorted(out.items())}


def snapshot(scene: Scene, data: mujoco.MjData, phase: str) -> dict[str, Any]:
    """What the scene shows at the end of ``phase`` (module docstring); world frame, SI units."""
    centre = scene.object_position(data)
    return {
        "phase": phase,
        "time": round(float(data.time), 4),
        "hand_contacts": hand_forces(scene, data),
        "touches_table": scene.object_touches_table(data),
        "height": round(float(centre[2]) - scene.table_height, 5),
        "offset": [round(float(v), 5) for v in scene.object_in_flange(data)],
    }


def summary(diagnosis: Mapping[str, Any]) -> str:
    """One line of a diagnosis (``{"phases": [...], "released_at": ...}``) for a person."""
    parts = []
    for snap in diagnosis.get("phases", []):
        contacts = snap["hand_contacts"]
        if snap["phase"] == "approach":
            if contacts:
                parts.append(f"the approach ended touching the object ({', '.join(contacts)})")
            continue
        if snap["phase"] == "closure":
            loaded = [f"{k} {v:.1f} N" for k, v in contacts.items()]
            text = f"closure ended with {len(contacts)} contact{'s' if len(contacts) != 1 else ''}"
            text += f" ({', '.join(loaded)})" if loaded else ": no contact"
            if contacts and all(v < NO_FORCE for v in contacts.values()):
                text += ", none loaded"
            parts.append(text)
            continue
        if snap["phase"] == "stopped":
            rule = (diagnosis.get("stopped") or {}).get("rule")
            if rule == "clear_alone":
                parts.append(f"stopped at {snap['time']:.2f} s with the object away from the hand, never to return")
            else:
                parts.append(f"stopped at {snap['time']:.2f} s with the object on the table, out of the hand's reach")
            continue
        where = "on the table" if snap["touches_table"] else f"{snap['height'] * 1000:.0f} mm above the table"
        held = f"held by {len(contacts)}" if contacts else "not in the hand"
        parts.append(f"{snap['phase']} ended with the object {where}, {held}")
    released = diagnosis.get("released_at")
    if released is not None:
        parts.append(f"the object left the hand at {released:.2f} s")
    return "; ".join(parts) if parts else "nothing simulated"
