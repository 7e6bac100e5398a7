"""The ``clear_alone`` stop rule: an object that left the hand, simulated alone, never comes near the robot again.

During the lift and the hold a dropped object often rolls away across the table (an apple falling from a few
centimetres bounces and rolls at 1-2 m/s): its kinetic energy keeps the ``out_of_reach`` rule of
:mod:`softsig_service.simulation.rollout` from deciding, yet it never meets the hand again. This rule decides it
from the object's own future instead of a bound on it:

1. **The robot's room** for the rest of the schedule (:class:`RoomTracks`): at the arm's joint targets of every
   remaining control tick and at its state now, the bounding sphere of every arm geom and of every hand geom rigid
   with the mount, and for each finger (a chain of jointed bodies) one sphere about its root's seat on the palm that
   holds it in *any* posture (:func:`hand_parts`: the lengths of the chain, so the fingers may close, open or sway as
   they like), each widened by ``clearance`` [m]; per sphere, the axis-aligned box that holds it at all those ticks
   (the lift moves the hand straight up, so a box is little more than the spheres it holds). The room covers every
   remaining target whatever the servos' lag behind them: on a rolling drop of Table I the robot's spheres as
   simulated left their boxes by at most 0.9 mm, against the 1 cm clearance.
2. **The object alone** (:func:`~softsig_service.simulation.scene.build_object_alone`: the same body, table and
   options) from its state now to the end of the schedule, tick by tick (:func:`follow_alone`): if its bounding
   sphere, widened by the contact margin, stays outside every box of that room now and at every time step (at each
   tick's end, widened further by the path it ran in the tick), nothing but the table touches it in the full scene
   either (MuJoCo solves its constraint island apart from the robot's), so it moves there as it does alone (to about
   1e-11 m, ``tests/simulation/test_approach_replay.py``) and is never touched by the hand again. The trial's outcome
   is then the full schedule's: the end state is the alone simulation's.

World frame (UR5 ``base_link``, z up), SI units.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.simulation.approach_replay import alone_tick
from softsig_service.simulation.scene_model import OBJECT_BODY, Scene, diverged

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class HandParts:
    """The hand split for :class:`RoomTracks`: ``rigid`` geoms move with the mount whatever the posture (their own
    bounding spheres); every other geom hangs below a ``root`` body, the jointed body nearest the mount on its chain,
    and lies within ``radius`` [m] of the point where that root's origin sits in its parent's frame (``root_pos``),
    in any posture. ``roots``, ``root_pos`` and ``radius`` are per root."""

    rigid: NDArray[np.int64]
    roots: NDArray[np.int64]
    root_pos: FloatArray
    radius: FloatArray


def _chain_reach(model: mujoco.MjModel, body: int) -> float:
    """[m] how far a body's origin can be from where it sits in its parent's frame: twice each hinge's or ball's
    offset from the body's origin (a turn about that point), a slide's longest travel from its reference position;
    infinite for a free joint or an unlimited slide."""
    reach = 0.0
    for j in range(int(model.body_jntadr[body]), int(model.body_jntadr[body] + model.body_jntnum[body])):
        kind = int(model.jnt_type[j])
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            return float("inf")
        if kind == mujoco.mjtJoint.mjJNT_SLIDE:  # it moves the body by q - qpos0 along its axis
            if not model.jnt_limited[j]:
                return float("inf")
            reach += float(np.max(np.abs(model.jnt_range[j] - model.qpos0[model.jnt_qposadr[j]])))
        reach += 2.0 * float(np.linalg.norm(model.jnt_pos[j]))
    return reach


@functools.lru_cache(maxsize=32)  # per scene model: a process builds a few
def _hand_parts(model: mujoco.MjModel, mount: int, geoms: tuple[int, ...]) -> HandParts:
    rigid: list[int] = []
    radius: dict[int, float] = {}
    for g in geoms:
        chain = []  # the bodies from the geom's up to (not including) the mount
        b = int(model.geom_bodyid[g])
        while b != mount:
            chain.append(b)
            b = int(model.body_parentid[b])
        jointed = [i for i, c in enumerate(chain) if model.body_jntnum[c] > 0]
        if not jointed:
            rigid.append(g)
            continue
        top = jointed[-1]  # the jointed body nearest the mount: the root
        reach = _chain_reach(model, chain[top])
        for c in chain[:top]:
            reach += float(np.linalg.norm(model.body_pos[c])) + _chain_reach(model, c)
        reach += float(np.linalg.norm(model.geom_pos[g])) + float(model.geom_rbound[g])
        radius[chain[top]] = max(radius.get(chain[top], 0.0), reach)
    roots = np.array(sorted(radius), dtype=np.int64)
    return HandParts(
        rigid=np.array(rigid, dtype=np.int64),
        roots=roots,
        root_pos=np.array([model.body_pos[r] for r in roots], dtype=np.float64).reshape(-1, 3),
        radius=np.array([radius[int(r)] for r in roots], dtype=np.float64),
    )


def hand_parts(scene: Scene) -> HandParts:
    """The scene's hand split into rigid geoms and jointed chains (:class:`HandParts`), computed once per model: a
    chain's radius is the sum, along it, of each body's offset from its parent and the travel its joints allow
    (:func:`_chain_reach`), plus the geom's offset and bounding radius."""
    return _hand_parts(scene.model, int(scene.mount_body), tuple(int(g) for g in scene.hand_geoms))


@dataclass(frozen=True)
class Room:
    """Axis-aligned boxes that hold the robot for the rest of a schedule: ``lo`` and ``hi`` (M, 3) [m], their
    lower and upper corners (world frame)."""

    lo: FloatArray
    hi: FloatArray


def _spheres(scene: Scene, data: mujoco.MjData, parts: HandParts) -> FloatArray:
    """The centres (M, 3) of the robot's spheres as posed in ``data`` (positions computed): the arm's and the rigid
    hand geoms' centres, then each chain root's seat in its parent's frame."""
    parents = scene.model.body_parentid[parts.roots]
    seats = data.xpos[parents] + np.einsum("nij,nj->ni", data.xmat[parents].reshape(-1, 3, 3), parts.root_pos)
    return np.concatenate([data.geom_xpos[scene.arm_geoms], data.geom_xpos[parts.rigid], seats])


def _radii(scene: Scene, parts: HandParts, clearance: float) -> FloatArray:
    m = scene.model
    return np.concatenate([m.geom_rbound[scene.arm_geoms], m.geom_rbound[parts.rigid], parts.radius]) + clearance


class RoomTracks:
    """The robot's spheres at the arm's joint targets ``arm_targets`` [rad] of a run of ticks (the hand's posture
    does not move them: :class:`HandParts`), widened by ``clearance`` [m], kept as the boxes that hold each sphere
    over every suffix of the run: :meth:`room` for the ticks from ``i`` on is one lookup."""

    def __init__(self, scene: Scene, data: mujoco.MjData, arm_targets: Sequence[FloatArray], clearance: float) -> None:
        self.scene, self.clearance = scene, clearance
        self.parts = hand_parts(scene)
        self.radii = _radii(scene, self.parts, clearance)
        m = scene.model
        probe = mujoco.MjData(m)
        probe.qpos[:] = data.qpos
        centres = np.empty((len(arm_targets), self.radii.size, 3))
        for t, q in enumerate(arm_targets):
            probe.qpos[scene.arm_qpos] = q
            mujoco.mj_kinematics(m, probe)
            centres[t] = _spheres(scene, probe, self.parts)
        r = self.radii[None, :, None]
        self.lo = np.minimum.accumulate((centres - r)[::-1], axis=0)[::-1]  # lo[i]: over ticks i..end
        self.hi = np.maximum.accumulate((centres + r)[::-1], axis=0)[::-1]

    def __len__(self) -> int:
        return int(self.lo.shape[0])

    def room(self, i: int, data: mujoco.MjData) -> Room:
        """The robot's room (module docstring, step 1) for the targets from the ``i``-th on and its state in
        ``data`` now."""
        now = _spheres(self.scene, data, self.parts)
        r = self.radii[:, None]
        return Room(np.concatenate([now - r, self.lo[i]]), np.concatenate([now + r, self.hi[i]]))


@dataclass(frozen=True)
class AloneEnd:
    """The object's end state from :func:`follow_alone`: its world height [m] after the last tick (as the scene
    reports it: the body's position at the start of that tick's last time step), the highest such height of any
    tick [m], and whether it touches the table there (a contact with distance <= 0)."""

    height: float
    max_height: float
    touches_table: bool


def _clear(room: Room, centre: FloatArray, radius: float) -> bool:
    """Whether the sphere (``centre`` [m], ``radius`` [m]) lies outside every box of ``room``."""
    out = np.maximum(np.maximum(room.lo - centre, centre - room.hi), 0.0)  # per box: how far outside, per axis
    return bool(np.min(np.einsum("ij,ij->i", out, out)) > radius * radius)


def follow_alone(
    scene: Scene, alone: mujoco.MjModel, data: mujoco.MjData, room: Room, ticks: int, nsub: int
) -> AloneEnd | None:
    """Simulate the object of ``data`` (the scene's data now) alone on the table for ``ticks`` control ticks of
    ``nsub`` time steps; its end state if its bounding sphere, widened by the scene's contact margin, stays outside
    every box of ``room`` now and at every time step (checked per tick: the sphere at the tick's end widened by the
    path its centre ran in the tick), else None (also when the alone simulation diverges)."""
    a = scene.object_qpos
    dof = int(scene.model.jnt_dofadr[scene.model.body_jntadr[scene.object_body]])
    d = mujoco.MjData(alone)
    d.qpos[:] = data.qpos[a : a + 7]
    d.qvel[:] = data.qvel[dof : dof + 6]
    d.qacc_warmstart[:] = data.qacc_warmstart[dof : dof + 6]
    d.time = data.time
    og, ob = int(alone.geom(f"{OBJECT_BODY}_geom").id), int(alone.body(OBJECT_BODY).id)
    r_obj = float(alone.geom_rbound[og]) + scene.contact_margin
    mujoco.mj_kinematics(alone, d)
    if not _clear(room, d.geom_xpos[og], r_obj):
        return None
    height = max_height = float(data.xpos[scene.object_body][2])
    for _ in range(ticks):
        height, path = alone_tick(alone, d, og, ob, nsub, 0.0)  # the sphere's centre: its path bounds every step's
        if diverged(d):
            return None
        max_height = max(max_height, height)
        if not _clear(room, d.geom_xpos[og], r_obj + path):
            return None
    touches = bool(d.ncon and np.any(d.contact.dist[: d.ncon] <= 0.0))
    return AloneEnd(height=height, max_height=max_height, touches_table=touches)
