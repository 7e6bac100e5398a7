"""Contacts between the hand and the object in a MuJoCo grasp: which hand geoms touch it and with what force.

Forces [N] and torques [N·m] in the world frame of the MuJoCo model (the hand frame for the grasp scene).
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

MIN_CONTACT_FORCE = 1e-6
"""Hand-object contacts with a normal force at or below this [N] are not part of the grasp."""


def contact_forces(
    model: mujoco.MjModel, data: mujoco.MjData, geom: int, body: int
) -> list[tuple[int, int, FloatArray, FloatArray]]:
    """Loaded hand-object contacts: (contact index, hand geom, force on the object (world) [N], normal into the
    object (world))."""
    out = []
    f6 = np.zeros(6)
    for i in range(data.ncon):
        con = data.contact[i]
        g1, g2 = int(con.geom1), int(con.geom2)
        if geom not in (g1, g2) or con.efc_address < 0:
            continue
        other = g2 if g1 == geom else g1
        other_body = int(model.geom_bodyid[other])
        if other_body in (0, body):
            continue
        mujoco.mj_contactForce(model, data, i, f6)
        frame = con.frame.reshape(3, 3)
        # mj_contactForce: the force geom1 exerts on geom2, in the contact frame (rows: normal, t1, t2; the
        # normal points from geom1 to geom2)
        f_world = frame.T @ f6[:3]
        normal = frame[0].copy()
        if g1 == geom:
            f_world, normal = -f_world, -normal
        if float(f_world @ normal) > MIN_CONTACT_FORCE:
            out.append((i, other, f_world, normal))
    return out


def net_contact_wrench(model: mujoco.MjModel, data: mujoco.MjData, geom: int, body: int) -> FloatArray:
    """Net wrench (force [N], torque [N·m] about the body's centre of mass; world frame) of the hand's contacts
    on the object."""
    w = np.zeros(6)
    c = data.xipos[body]
    for i, _, f, _ in contact_forces(model, data, geom, body):
        w[:3] += f
        w[3:] += np.cross(data.contact[i].pos - c, f)
    return w
