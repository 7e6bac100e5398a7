"""Approach replay: the trials of one plan share the robot's motion until just before the hand touches the object.

Every trial of a campaign cell plans on the nominal object pose, so its arm and hand follow the same joint targets
and, until they touch the object, the same motion: MuJoCo solves the robot's constraint island apart from the
object's, and the robot's state at a control tick is the same, bit for bit, whatever the object's pose as long as
nothing of the robot has touched it (``tests/simulation/test_approach_replay.py``). A trial therefore need not
simulate the robot through the approach and the closure again:

1. **Record** (once per scene, plan and schedule in a process, :class:`PrefixRecorder`): the approach and the
   closure simulated with the object far from the robot (:data:`FAR` along world x, on the table plane); at every
   control tick the full state (``qpos``, ``qvel``, ``act``, ``ctrl``, ``qacc_warmstart``, time) and the poses of
   the hand's and the arm's geoms, and the travel bound: how far any point of those geoms moved since the tick
   before (``|dx| + |dR|_F r`` per geom, ``r`` its bounding radius).
2. **Replay** (per trial, :func:`replay`): the object alone on the table
   (:func:`~softsig_service.simulation.scene.build_object_alone`, its island as in the scene) from the trial's pose,
   tick by tick, and at each tick the distance (MuJoCo's ``mj_geomDistance``) between the object and every hand or
   arm geom posed as recorded. A tick is shared while nothing of the robot can have touched the object during it: the
   distance at the tick before exceeds, by :data:`MARGIN`, how far the robot's points (the recorded travel bound) and
   the object's points (likewise, along its replayed poses at every time step) moved in the tick, and the contact
   margin. The trial resumes at the last shared tick (the fingers are then a few millimetres from the object,
   typically early in the closure), and at the latest one tick before the closure ends.
3. **Resume**: the scene's data at that tick is the recorded robot state with the object's replayed state; the
   trial's record of the skipped ticks (the object's highest rise, its settling, the first arm-table contact) comes
   from the replay and the recording. From there the full scene is simulated as before.

The object's replayed state agrees with the one the full scene gives to about 1e-11 m (floating-point rounding of
the two models' different sizes); the robot's is the same. Used only when nothing records frames or phases and the
scene has no obstacles (they move with the hand's pushes).
"""

from __future__ import annotations

import hashlib
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.simulation.scene_model import OBJECT_BODY, Scene, diverged

FloatArray = NDArray[np.float64]

NEAR = 0.01
"""[m] the distances between the object and the robot's geoms are computed up to this (``mj_geomDistance``'s
``distmax``; a larger gap counts as this much): servo motion moves the hand's points a few millimetres per 10 ms
tick at most, so a tick whose motion reaches it ends the shared part."""
MARGIN = 0.001
"""[m] what a tick's gap must exceed the robot's and the object's motion in that tick by to be shared (covers the
difference between the motion within a tick and the straight line between its end poses)."""
FAR = 100.0
"""[m] how far along world x the recording puts the object (on the table plane, out of every robot geom's reach)."""
CACHE_SIZE = 16
"""Recorded prefixes kept per scene (a campaign cell needs one per plan)."""


@dataclass(frozen=True, eq=False)
class Prefix:
    """The robot's recorded states at the control ticks 0 (the start) to ``n`` of the approach and the closure.

    Attributes:
        qpos, qvel, act, ctrl, warmstart: the scene's state after each tick (rows 0..n; row 0 the start).
        time: [s] simulated time after each tick.
        geom_xpos, geom_xmat: poses of :attr:`geoms` (world frame, [m]) after each tick, from the tick's positions.
        geoms: the hand's and the arm's geom ids.
        travel: [m] bound of how far any point of those geoms moved during each tick (``travel[0] = 0``).
        n_approach: the tick at which the approach ends (the closure runs from there to ``n``).
        arm_collision_time: [s] the first arm-table contact in the recording (None: none).
    """

    qpos: FloatArray
    qvel: FloatArray
    act: FloatArray
    ctrl: FloatArray
    warmstart: FloatArray
    time: FloatArray
    geom_xpos: FloatArray
    geom_xmat: FloatArray
    geoms: NDArray[np.int64]
    travel: FloatArray
    n_approach: int
    arm_collision_time: float | None

    @property
    def n(self) -> int:
        """The last recorded tick."""
        return int(self.time.size - 1)


class PrefixRecorder:
    """Collects a :class:`Prefix` from a rollout of the scene with the object at :data:`FAR` (call :meth:`tick`
    after every control tick, :meth:`prefix` at the end)."""

    def __init__(self, scene: Scene, data: mujoco.MjData) -> None:
        self.scene, self.data = scene, data
        self.geoms = np.concatenate([scene.hand_geoms, scene.arm_geoms]).astype(np.int64)
        self.probe = mujoco.MjData(scene.model)
        self.rows: list[tuple[FloatArray, ...]] = []
        self.tick()

    def tick(self) -> None:
        """Record the state after a tick (and the geoms' poses from its positions)."""
        d, probe = self.data, self.probe
        probe.qpos[:] = d.qpos
        mujoco.mj_kinematics(self.scene.model, probe)
        self.rows.append((d.qpos.copy(), d.qvel.copy(), d.act.copy(), d.ctrl.copy(), d.qacc_warmstart.copy(),
                          np.array([d.time]), probe.geom_xpos[self.geoms].copy(),
                          probe.geom_xmat[self.geoms].copy()))  # fmt: skip

    def prefix(self, n_approach: int, arm_collision_time: float | None) -> Prefix:
        """The recorded ticks as a :class:`Prefix`."""
        cols = [np.array([row[i] for row in self.rows]) for i in range(8)]
        xpos, xmat = cols[6], cols[7]
        rbound = self.scene.model.geom_rbound[self.geoms]
        travel = np.zeros(len(self.rows))
        if len(self.rows) > 1:
            dx = np.linalg.norm(np.diff(xpos, axis=0), axis=2)
            dR = np.linalg.norm(np.diff(xmat, axis=0), axis=2)
            travel[1:] = np.max(dx + dR * rbound, axis=1)
        return Prefix(qpos=cols[0], qvel=cols[1], act=cols[2], ctrl=cols[3], warmstart=cols[4], time=cols[5][:, 0],
                      geom_xpos=xpos, geom_xmat=xmat, geoms=self.geoms, travel=travel, n_approach=n_approach,
                      arm_collision_time=arm_collision_time)  # fmt: skip


@dataclass(frozen=True)
class Replay:
    """What a trial takes from the replay: resume at tick ``tick``, with the object's state there.

    Attributes:
        tick: the tick to resume at (0: simulate everything).
        qpos, qvel, warmstart: the object's free joint (7), its dofs (6) and their warm start at ``tick``.
        heights: [m] the object body's world z after each tick 1..``tick`` (as the scene reports it after a tick).
        approach_end: the object's qpos at the end of the approach, if ``tick`` is past it (else None).
    """

    tick: int
    qpos: FloatArray
    qvel: FloatArray
    warmstart: FloatArray
    heights: FloatArray
    approach_end: FloatArray | None


def replay(scene: Scene, alone: mujoco.MjModel, start: mujoco.MjData, prefix: Prefix, nsub: int) -> Replay:
    """Simulate the object alone from the trial's start ``start`` (the scene's data, the object at its pose) along
    ``prefix`` until the robot may touch it (module docstring); ``nsub`` time steps per tick."""
    a = scene.object_qpos
    dof = int(scene.model.jnt_dofadr[scene.model.body_jntadr[scene.object_body]])
    d = mujoco.MjData(alone)
    d.qpos[:] = start.qpos[a : a + 7]
    d.qvel[:] = start.qvel[dof : dof + 6]
    mujoco.mj_forward(alone, d)
    probe = mujoco.MjData(scene.model)
    obj_geom = int(scene.object_geoms[0])
    og, ob = int(alone.geom(f"{OBJECT_BODY}_geom").id), int(alone.body(OBJECT_BODY).id)
    r_obj = float(scene.model.geom_rbound[obj_geom])
    rbound = scene.model.geom_rbound[prefix.geoms]
    last = prefix.n - 1  # at least one tick of the closure is simulated in the scene
    states = [(d.qpos.copy(), d.qvel.copy(), d.qacc_warmstart.copy())]
    heights: list[float] = []
    approach_end: FloatArray | None = None
    x_prev, R_prev = d.geom_xpos[og].copy(), d.geom_xmat[og].copy()
    margin = MARGIN + scene.contact_margin  # a pair closer than its margin makes a contact
    for k in range(1, last + 1):
        z, moved = alone_tick(alone, d, og, ob, nsub, r_obj)
        if diverged(d):
            break
        need = moved + prefix.travel[k] + margin  # the gap at the tick before must exceed this
        if need >= NEAR or _gap(scene.model, probe, prefix, k - 1, obj_geom, x_prev, R_prev, rbound, need) < need:
            break  # something of the robot may have touched the object in this tick
        x_prev, R_prev = d.geom_xpos[og].copy(), d.geom_xmat[og].copy()
        heights.append(z)
        states.append((d.qpos.copy(), d.qvel.copy(), d.qacc_warmstart.copy()))
        if k == prefix.n_approach:
            approach_end = d.qpos.copy()
    tick = len(states) - 1
    qpos, qvel, warm = states[tick]
    return Replay(tick=tick, qpos=qpos, qvel=qvel, warmstart=warm, heights=np.array(heights),
                  approach_end=approach_end if tick >= prefix.n_approach else None)  # fmt: skip


def alone_tick(
    alone: mujoco.MjModel, d: mujoco.MjData, geom: int, body: int, nsub: int, r: float
) -> tuple[float, float]:
    """One control tick (``nsub`` time steps) of the object alone (``d``'s positions computed at its start, as this
    leaves them at its end): the body's world height [m] as the scene reports it after a tick (the last step's
    start), and the path [m] of ``geom``'s points through the poses its steps start from (where MuJoCo makes
    contacts) to the tick's end, ``|dx| + |dR|_F r`` per move (``r``: the radius whose points count; 0 for the
    centre alone)."""
    x0, R0 = d.geom_xpos[geom].copy(), d.geom_xmat[geom].copy()
    path = 0.0

    def moved() -> float:  # from (x0, R0) to the poses in d now
        nonlocal x0, R0
        x, R = d.geom_xpos[geom], d.geom_xmat[geom]
        step = float(np.linalg.norm(x - x0)) + (float(np.linalg.norm(R - R0)) * r if r else 0.0)
        x0, R0 = x.copy(), R.copy()
        return step

    for j in range(nsub):
        mujoco.mj_step(alone, d)  # leaves the poses the step started from (the first step's: the tick's start)
        if j > 0:
            path += moved()
    height = float(d.xpos[body][2])
    mujoco.mj_kinematics(alone, d)  # the tick's end
    return height, path + moved()


def _gap(
    model: mujoco.MjModel,
    probe: mujoco.MjData,
    prefix: Prefix,
    k: int,
    obj_geom: int,
    x: FloatArray,
    R: FloatArray,
    rbound: FloatArray,
    cap: float = NEAR,
) -> float:
    """[m] the least distance (capped at ``cap``) between the object geom at (``x``, ``R``) and the robot's geoms as
    recorded at tick ``k`` (bounding spheres first, then ``mj_geomDistance``)."""
    centre = np.linalg.norm(prefix.geom_xpos[k] - x, axis=1) - rbound - float(model.geom_rbound[obj_geom])
    near = np.flatnonzero(centre < cap)
    if near.size == 0:
        return cap
    probe.geom_xpos[obj_geom], probe.geom_xmat[obj_geom] = x, R
    gap = cap
    for i in near:
        g = int(prefix.geoms[i])
        probe.geom_xpos[g], probe.geom_xmat[g] = prefix.geom_xpos[k, i], prefix.geom_xmat[k, i]
        gap = min(gap, float(mujoco.mj_geomDistance(model, probe, g, obj_geom, cap, None)))
    return gap


def restore(scene: Scene, data: mujoco.MjData, prefix: Prefix, rp: Replay) -> None:
    """Set ``data`` to the recorded robot state at ``rp.tick`` with the object's replayed state."""
    k, a = rp.tick, scene.object_qpos
    dof = int(scene.model.jnt_dofadr[scene.model.body_jntadr[scene.object_body]])
    data.qpos[:] = prefix.qpos[k]
    data.qvel[:] = prefix.qvel[k]
    data.act[:] = prefix.act[k]
    data.ctrl[:] = prefix.ctrl[k]
    data.qacc_warmstart[:] = prefix.warmstart[k]
    data.qpos[a : a + 7] = rp.qpos
    data.qvel[dof : dof + 6] = rp.qvel
    data.qacc_warmstart[dof : dof + 6] = rp.warmstart
    data.time = float(prefix.time[k])


_CACHE: weakref.WeakKeyDictionary[Scene, OrderedDict[bytes, Prefix]] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


def cached_prefix(
    scene: Scene, key_parts: tuple[object, ...], approach: FloatArray, make: Callable[[], Prefix]
) -> Prefix:
    """The prefix of ``scene`` for the approach path ``approach`` (K, 6) [rad] and the schedule ``key_parts``,
    recorded by ``make`` the first time (per process; at most :data:`CACHE_SIZE` per scene, least recently used
    dropped)."""
    h = hashlib.blake2b(np.ascontiguousarray(approach, dtype=np.float64).tobytes(), digest_size=16)
    h.update(repr(key_parts).encode())
    key = h.digest()
    with _LOCK:
        per_scene = _CACHE.setdefault(scene, OrderedDict())
        found = per_scene.get(key)
        if found is not None:
            per_scene.move_to_end(key)
            return found
    prefix = make()
    with _LOCK:
        per_scene = _CACHE.setdefault(scene, OrderedDict())
        per_scene[key] = prefix
        while len(per_scene) > CACHE_SIZE:
            per_scene.popitem(last=False)
    return prefix
