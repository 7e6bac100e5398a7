"""The MuJoCo rollout of a planned top grasp: perturb the object, approach, close, lift, hold, judge.

The sequence (docs/design.md §7), all in the world frame (UR5 ``base_link``, z up), SI units:

1. **Plan** on the *nominal* object pose (done by the caller, :func:`softsig_service.experiments.trial.run_trial`):
   a plan that fails ends the trial with the plan's first reason (``unreachable``, ``collision:table``, ...).
2. **Perturb** the simulated object: yaw about its vertical axis by ``d_yaw ~ N(0, sigma_r^2)`` [rad] and
   shift in x, y by ``(dx, dy) ~ N(0, sigma_t^2)`` [m] each, drawn from ``numpy.random.default_rng(seed)`` in
   the order ``d_yaw, dx, dy`` (always drawn, also for sigma = 0). The object rests on the table.
3. **Pre-grasp**: the arm starts at the plan's pre-grasp joint positions (servo targets there too), the hand
   open (posture closures: the open posture), at rest.
4. **Approach**: joint targets from IK at :attr:`RolloutConfig.waypoints` points of the straight Cartesian line
   from the pre-grasp to the grasp flange pose (each IK seeded by the previous solution), interpolated
   linearly in joint space along a quintic time scaling over :attr:`RolloutConfig.approach_time` [s]. The
   joint servos (no velocity feed-forward) lag up to about 1.5 cm along the path at peak speed and stay within
   about 1 mm of the line (3 mm during the lift); they settle within 1 mm of the target at the end.
5. **Close**: the hand's closure command ramps linearly from open to closed over the manifest's
   ``closure.duration`` [s] and is held ``closure.settle`` [s] (exactly as the free-space closure that the CS
   is computed from, :func:`softsig_service.hands.closure.closure_command`); the arm holds the grasp.
6. **Lift**: the flange rises :attr:`RolloutConfig.lift` [m] (0.15) along world +z, IK along the line, over
   :attr:`RolloutConfig.lift_time` [s]; the closure command stays closed.
7. **Hold** for :attr:`RolloutConfig.hold_time` [s] (1 s).

**Judge** (docs/design.md §7): success iff the hand **carries** the object at the end of the hold, i.e. all of

* the object touches the hand (a MuJoCo contact, distance <= 0, between an object geom and a hand geom);
* the object is off the table (no contact, distance <= 0, between an object geom and the table);
* the object's centre rose by at least ``success_fraction * lift`` (half of 0.15 m = 0.075 m) between the
  start of the trial and the end of the hold,

and the trial was not stopped before: a failed plan, a diverged simulation or an arm collision fail it
whatever the object did. A compliant hand lets a carried object sag and slip; both are reported as figures
(:class:`TrialResult`), never as a reason to fail a carried object:

* **sag** [m] = ``lift`` - rise: how far the object's centre stayed below the flange's rise (0 for an object
  that moved exactly with the flange; about ``lift`` for an object left on the table);
* **slip** [m] = ``|p_end - p_hold|``, where ``p = R_flange^T (c_object - o_flange)`` is the position of the
  object's centre expressed in the flange (``tool0`` = hand) frame, taken at the start of the hold
  (``p_hold``, the end of the lift) and at its end (``p_end``): the object's displacement relative to the hand
  during the hold (0 for ``hold_time`` = 0).

A failed trial says why, checked in this order:

* the plan's first reason (``unreachable``, ``unreachable:approach``, ``collision:table``,
  ``alignment_impossible``...), or ``unreachable:approach`` / ``unreachable:lift`` if the IK along the approach
  or the lift line fails here (the planner does not check the lift);
* ``sim_unstable``: the simulation diverged (non-finite state or a MuJoCo warning);
* ``arm_collision``: an arm link (not the hand) touched the table at any control tick, or the object before
  the lift (during the approach or the closure). Once the object is in the hand, its contacts with the arm's
  wrist (held against the flange, or falling past it) are not arm collisions;
* ``not_lifted``: the object touches the hand at the end but still touches the table or rose less than the
  threshold (it stays on the table, is dragged along it, or hangs low);
* ``dropped``: the object touched the hand at the end of the closure or at some control tick of the lift or
  the hold, but not at the end of the hold;
* ``no_contact``: the object touched the hand neither at the end of the closure nor at any time after it.

**Early stop** (:attr:`RolloutConfig.early_stop`, on by default): a trial whose outcome is decided before its
schedule ends stops there (:data:`STOP_RULES`): a diverged simulation, or, during the lift or the hold, an object
lying at rest on the table out of the rising hand's reach, or one whose own simulation alone to the end of the
schedule never brings it near the robot (:mod:`softsig_service.simulation.clear_alone`: it rolls away; its end
state is taken from that simulation). The verdict, ``dropped`` or ``no_contact``, is the one the full schedule
gives; the stop is recorded in :attr:`SimOutcome.stopped`. A carried object is always held to the end of the
hold.

**Approach replay** (:attr:`RolloutConfig.replay_approach`, on by default): the trials of one plan follow the same
joint targets, so the robot's motion until it may touch the object (through the approach and typically into the
closure) is recorded once per process and plan, and a trial simulates only its object (alone on the table) up to
there and resumes the full scene at that tick
(:mod:`softsig_service.simulation.approach_replay`: the robot's state there is the full simulation's bit for bit,
the object's to about 1e-11 m). Off when frames or phases are recorded or the scene has obstacles.

A trial is deterministic for a seed: same seed, same perturbation, same plan, same simulation, same outcome
(MuJoCo is deterministic on one machine and build).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.arm.trajectory import APPROACH_TIME, LIFT, LIFT_TIME, WAYPOINTS, interp, quintic
from softsig_service.errors import InvalidInput
from softsig_service.hands.closure import closure_command
from softsig_service.objects import TableObject
from softsig_service.simulation.approach_replay import (
    FAR,
    Prefix,
    PrefixRecorder,
    Replay,
    cached_prefix,
    replay,
    restore,
)
from softsig_service.simulation.clear_alone import AloneEnd, RoomTracks, follow_alone
from softsig_service.simulation.diagnosis import snapshot
from softsig_service.simulation.scene import build_object_alone
from softsig_service.simulation.scene_model import ContactSummary, Scene, diverged

FloatArray = NDArray[np.float64]

REASONS: tuple[str, ...] = (
    "unreachable:approach",
    "unreachable:lift",
    "sim_unstable",
    "arm_collision",
    "not_lifted",
    "dropped",
    "no_contact",
)
"""Failure reasons of the simulation (a failed plan gives the planner's own reasons instead)."""


@dataclass(frozen=True)
class RolloutConfig:
    """Timing and thresholds of a trial (SI units).

    Attributes:
        lift: [m] height the flange rises after closing (docs/design.md §7: 0.15).
        success_fraction: a carried object must have risen by at least this fraction of ``lift``
            (docs/design.md §7: 0.5, i.e. 0.075 m of a 0.15 m lift).
        approach_time: [s] nominal duration of the straight approach from the pre-grasp to the grasp (longer where
            the joints' limits need it: :func:`softsig_service.arm.trajectory.duration`).
        lift_time: [s] nominal duration of the lift (likewise).
        hold_time: [s] duration of the hold at the top (docs/design.md §7: 1 s).
        control_period: [s] period of the controller (servo targets updated, contacts checked); a multiple
            of the scene's time step (rounded to one).
        waypoints: number of IK waypoints along each Cartesian line (approach, lift), ends included.
        early_stop: end a trial as soon as its outcome is decided (:data:`STOP_RULES`); the verdict is the one
            the full schedule gives (``tests/simulation/test_early_stop.py`` checks it on every Table I cell).
        replay_approach: take the robot's motion up to the tick before it may touch the object from a recording
            shared by the trials of one plan (:mod:`softsig_service.simulation.approach_replay`; only when nothing
            records frames or phases and the scene has no obstacles).
    """

    lift: float = LIFT
    success_fraction: float = 0.5
    approach_time: float = APPROACH_TIME
    lift_time: float = LIFT_TIME
    hold_time: float = 1.0
    control_period: float = 0.01
    waypoints: int = WAYPOINTS
    early_stop: bool = True
    replay_approach: bool = True

    def __post_init__(self) -> None:
        for name in ("lift", "approach_time", "lift_time", "control_period"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise InvalidInput("must be a positive number", field=name, value=v)
        if not (math.isfinite(self.hold_time) and self.hold_time >= 0.0):
            raise InvalidInput("must be >= 0", field="hold_time", value=self.hold_time)
        if not (0.0 < self.success_fraction <= 1.0):
            raise InvalidInput("must lie in (0, 1]", field="success_fraction", value=self.success_fraction)
        if self.waypoints < 2:
            raise InvalidInput("need at least 2 waypoints", field="waypoints", value=self.waypoints)


@dataclass(frozen=True)
class Perturbation:
    """The simulated object's offset from the nominal pose: yaw [rad] about world z, shift x, y [m]."""

    d_yaw: float
    dx: float
    dy: float

    @staticmethod
    def draw(seed: int, sigma_r: float, sigma_t: float) -> Perturbation:
        """``d_yaw ~ N(0, sigma_r^2)``, then ``dx, dy ~ N(0, sigma_t^2)`` from ``default_rng(seed)``."""
        rng = np.random.default_rng(seed)
        d_yaw = float(rng.normal(0.0, 1.0)) * sigma_r
        dx, dy = (float(v) * sigma_t for v in rng.normal(0.0, 1.0, 2))
        return Perturbation(d_yaw, dx, dy)

    def apply(self, obj: TableObject) -> TableObject:
        """The object moved by this perturbation (an explicit centre height is kept; else it rests on the table)."""
        # keeps an explicit centre height (an object held above the table stays at that height)
        return dataclasses.replace(obj, x=obj.x + self.dx, y=obj.y + self.dy, yaw=obj.yaw + self.d_yaw)


FrameCallback = Callable[[Scene, mujoco.MjData], None]
"""Called with the scene and its data at the frame rate of a recording (and once at the start)."""


class PhaseObserver(Protocol):
    """Sees a simulated trial at its start and at the end of each phase, where the diagnosis snapshots are taken
    (the keyframes of :mod:`softsig_service.simulation.keyframes`). A rollout given none calls nothing."""

    def start(self, scene: Scene, data: mujoco.MjData, arm_poses: Sequence[FloatArray]) -> None:
        """The trial's first state; ``arm_poses``: the arm's joint positions [rad] at the pre-grasp, the grasp and
        the top of the lift."""

    def phase_end(self, scene: Scene, data: mujoco.MjData, snapshot: Mapping[str, Any]) -> None:
        """The state at the end of a phase (or at the early stop), with its diagnosis snapshot
        (:func:`softsig_service.simulation.diagnosis.snapshot`)."""


SETTLE_DROP = 0.001
"""[m] an object whose centre fell more than this during the approach was given above the table: it settled
(an object resting on the table sinks by well under it into the soft contact)."""


OUT_OF_REACH_CLEARANCE = 0.01
"""[m] the least gap between the hand's lowest point and the highest point the object could still reach that puts
it out of reach (covers the servos' few-mm tracking error and the closed fingers' sway)."""

CLEAR_ALONE_RETRY = 10
"""Control ticks between two tries of the ``clear_alone`` rule (each simulates the object alone to the end)."""

STOP_RULES: dict[str, str] = {
    "out_of_reach": (
        "during the lift or the hold, in a scene without obstacles, the object touches nothing but the table and "
        "the lowest point of the hand's geoms lies at least OUT_OF_REACH_CLEARANCE above the highest point the "
        "object can still reach: its centre of mass at most (|v| + |w| r)^2 / (2 g) above where it is (its kinetic "
        "energy bounds the rise; v, w its linear and angular velocity, r its farthest point from its origin) plus "
        "its farthest point from its centre of mass. The hand only rises (lift) or stays (hold) from there and "
        "the arm's links ride above it, so the object is never touched again: the trial ends 'dropped' (it was "
        "in the hand) or 'no_contact' (it never was), as the full schedule would"
    ),
    "clear_alone": (
        "during the lift or the hold, in a scene without obstacles, the object touches neither the hand nor the arm, "
        "and the object simulated alone on the table from its state now to the end of the schedule keeps its "
        "bounding sphere, at every time step, outside the robot's room: boxes holding the bounding spheres of the "
        "arm's geoms and of the hand's geoms rigid with its mount at the joint targets of every remaining tick and "
        "now, and per finger a sphere about its root that holds it in any posture, each widened by "
        "OUT_OF_REACH_CLEARANCE and the contact margin (softsig_service.simulation.clear_alone). Nothing but the "
        "table touches it in the full scene either, so it moves there as it does alone and the hand never touches "
        "it again: the trial ends 'dropped' or 'no_contact', with the end state of the alone simulation, as the "
        "full schedule would (an object that rolls away across the table)"
    ),
    "diverged": "the simulation diverged (non-finite state or a MuJoCo warning): 'sim_unstable'",
}
"""Why a simulated trial may end before its schedule does (:attr:`RolloutConfig.early_stop`); the
``diverged`` rule applies always."""


@dataclass
class SimOutcome:
    """What a simulated trial records for the judge (world frame, SI units).

    Attributes:
        rise: [m] rise of the object's centre from the start of the trial to the end of the hold.
        max_rise: [m] the largest rise at any control tick.
        touching_end: object-hand contact at the end of the hold.
        touching_table_end: object-table contact at the end of the hold.
        touching_after_close: object-hand contact at the end of the closure.
        touched_in_lift: object-hand contact at some control tick of the lift or the hold.
        arm_collision_time: [s] sim time of the first arm collision (None: none).
        unstable: the simulation diverged.
        sim_time: [s] simulated time.
        slip: [m] the object's displacement in the flange frame during the hold (None: not reached).
        settle_drop: [m] how far the object's centre fell during the approach, before the hand closed: an object
            given above the table falls onto it and settles (its rise is then counted from where it came to
            rest); about 0 for an object resting on the table. None when the approach did not end.
    """

    rise: float = 0.0
    max_rise: float = 0.0
    touching_end: bool = False
    touching_table_end: bool = False
    touching_after_close: bool = False
    touched_in_lift: bool = False
    arm_collision_time: float | None = None
    unstable: bool = False
    sim_time: float = 0.0
    slip: float | None = None
    settle_drop: float | None = None
    phases: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    """What the scene showed at the end of each phase run (:func:`softsig_service.simulation.diagnosis.snapshot`)."""
    released_at: float | None = None
    """[s] the first moment of the lift or hold at which the object touched no part of the hand, when the closure
    had ended in contact (None: never)."""
    stopped: dict[str, Any] | None = None
    """The trial ended before its schedule: ``{"rule": <a key of STOP_RULES>, "time": [s]}`` (None: it ran to the
    end, or stopped on a failed IK)."""


def judge(sim: SimOutcome, cfg: RolloutConfig) -> str | None:
    """The verdict on a simulated trial: None if the hand carries the object, else the reason (module
    docstring, docs/design.md §7). Sag and slip never fail a carried object."""
    if sim.unstable:
        return "sim_unstable"
    if sim.arm_collision_time is not None:
        return "arm_collision"
    if sim.touching_end:
        carried = not sim.touching_table_end and sim.rise >= cfg.success_fraction * cfg.lift
        return None if carried else "not_lifted"
    if sim.touching_after_close or sim.touched_in_lift:
        return "dropped"
    return "no_contact"


class Run:
    """One rollout in MuJoCo: the scene's data, started at the joint positions ``q_start`` [rad] with the object at
    its (perturbed) pose, stepped one control tick at a time while recording what the judge needs (``out``).

    ``tick`` [s] is the control period rounded to a whole number (``nsub``) of the scene's time steps; ``z0`` [m]
    the object's starting height (world z). :func:`simulate` drives it through the trial's phases.
    """

    def __init__(
        self, scene: Scene, obj: TableObject, q_start: FloatArray, cfg: RolloutConfig, pose: FloatArray | None = None
    ) -> None:
        self.scene = scene
        self.data = scene.make_data(q_start, obj.primitive_pose if pose is None else pose)
        self.z0 = float(scene.object_position(self.data)[2])
        self.out = SimOutcome()
        self.dt = float(scene.model.opt.timestep)
        self.nsub = max(1, round(cfg.control_period / self.dt))
        self.tick = self.nsub * self.dt
        self.early_stop = cfg.early_stop and scene.obstacle_geoms.size == 0
        self.object_dof = int(scene.model.jnt_dofadr[scene.model.body_jntadr[scene.object_body]])
        self.gravity = float(np.linalg.norm(scene.model.opt.gravity))
        self.done = 0  # control ticks run (or replayed) so far
        self.replayed: Replay | None = None
        self.prefix: Prefix | None = None
        self.obj = obj
        self.tail: list[tuple[int, Callable[[float], FloatArray]]] = []  # grasping phases after the current one
        self.targets: tuple[Callable[[float], FloatArray], int, int] | None = None  # arm, tick in phase, ticks
        self.alone_end: AloneEnd | None = None
        self.next_alone_try = 0  # the first tick at which the clear_alone rule is tried (again)
        self.room_tracks: tuple[int, RoomTracks] | None = None  # the tick they start after, the robot's room

    def resume(self, prefix: Prefix, rp: Replay) -> None:
        """Continue from tick ``rp.tick`` of a recorded approach (:mod:`softsig_service.simulation.approach_replay`):
        the data set there; the ticks before are replayed by :meth:`phase` from the record."""
        restore(self.scene, self.data, prefix, rp)
        self.replayed, self.prefix = rp, prefix
        t_hit = prefix.arm_collision_time
        if t_hit is not None and t_hit <= float(prefix.time[rp.tick]) + 1e-9:
            self.out.arm_collision_time = t_hit

    def in_replay(self) -> bool:
        """Whether every tick so far was replayed (the data holds the resumed state, not yet stepped)."""
        return self.replayed is not None and 0 < self.done <= self.replayed.tick

    def object_height(self) -> float:
        """[m] the object's world z after the last tick (replayed or simulated)."""
        if self.replayed is not None and self.in_replay():
            return float(self.replayed.heights[self.done - 1])
        return float(self.scene.object_position(self.data)[2])

    def step(self, grasping: bool) -> bool:
        """One control tick with the controls as set; False if the trial ends here (the simulation diverged, or
        its outcome is decided: :attr:`SimOutcome.stopped`).

        ``grasping``: the object is (meant to be) in the hand (lift and hold), so its contacts with the arm's
        links (held against the flange, or falling past the wrist) are not arm collisions, and its contacts
        with the hand are recorded in ``touched_in_lift``."""
        scene, data, out = self.scene, self.data, self.out
        t_start = float(data.time)
        mujoco.mj_step(scene.model, data, self.nsub)
        # MuJoCo resets a diverged state (time back to 0): a tick that ends early diverged; a tick from 0 (where
        # the reset's time may look right) reads the warnings themselves
        reset = data.time < t_start + (self.nsub - 0.5) * self.dt or (t_start < self.dt and diverged(data))
        if reset or not np.isfinite(data.qpos).all():
            out.unstable = True
            out.stopped = {"rule": "diverged", "time": round(t_start + self.tick, 4)}
            return False
        contacts = scene.contact_summary(data)
        arm_hit = contacts.arm_table or contacts.arm_obstacle or (contacts.arm_object and not grasping)
        if arm_hit and out.arm_collision_time is None:
            out.arm_collision_time = float(data.time)
        if grasping and contacts.object_hand:
            out.touched_in_lift = True
        elif grasping and out.touching_after_close and out.released_at is None:
            out.released_at = float(data.time)
        out.max_rise = max(out.max_rise, float(scene.object_position(data)[2]) - self.z0)
        if grasping and self.early_stop and self._out_of_reach(contacts):
            out.stopped = {"rule": "out_of_reach", "time": round(float(data.time), 4)}
            return False
        if grasping and self.early_stop and self._clear_alone(contacts):
            out.stopped = {"rule": "clear_alone", "time": round(float(data.time), 4)}
            return False
        return True

    def _remaining_targets(self) -> list[FloatArray]:
        """The arm's joint targets [rad] of every tick left in the schedule after this one."""
        if self.targets is None:
            return []
        arm, k, n = self.targets
        out = [arm((j + 1) * self.tick) for j in range(k + 1, n)]
        for n_ticks, fn in self.tail:
            out += [fn((j + 1) * self.tick) for j in range(n_ticks)]
        return out

    def _clear_alone(self, contacts: ContactSummary) -> bool:
        """Whether the ``clear_alone`` rule of :data:`STOP_RULES` holds now (tried at most every
        :data:`CLEAR_ALONE_RETRY` ticks while the object is out of the hand)."""
        if contacts.object_hand or contacts.arm_object or self.done < self.next_alone_try:
            return False
        if self.scene.object_geoms.size != 1 or self.scene.stray_colliders:
            return False
        self.next_alone_try = self.done + CLEAR_ALONE_RETRY
        if self.room_tracks is None:  # the rest of the schedule's targets, once per trial (later tries: a suffix)
            targets = self._remaining_targets()
            if not targets:
                return False
            clearance = OUT_OF_REACH_CLEARANCE + self.scene.contact_margin
            self.room_tracks = (self.done, RoomTracks(self.scene, self.data, targets, clearance))
        start, tracks = self.room_tracks
        i = self.done - start
        if i >= len(tracks):
            return False
        alone = build_object_alone(self.obj, self.scene)
        room = tracks.room(i, self.data)
        self.alone_end = follow_alone(self.scene, alone, self.data, room, len(tracks) - i, self.nsub)
        return self.alone_end is not None

    def _out_of_reach(self, contacts: ContactSummary) -> bool:
        """Whether the ``out_of_reach`` rule of :data:`STOP_RULES` holds now."""
        if contacts.object_hand or contacts.arm_object:
            return False
        scene, data = self.scene, self.data
        hand_low, _ = scene.vertical_extent(data, scene.hand_geoms)
        v = data.qvel[self.object_dof : self.object_dof + 6]
        r_origin, r_com = scene.object_reach
        speed = float(np.linalg.norm(v[:3])) + float(np.linalg.norm(v[3:])) * r_origin  # bounds every point's
        rise = speed * speed / (2.0 * self.gravity) if self.gravity > 0.0 else math.inf
        reach = float(data.xipos[scene.object_body][2]) + rise + r_com
        return hand_low >= reach + OUT_OF_REACH_CLEARANCE

    def ticks(self, duration: float) -> int:
        """The control ticks a phase of ``duration`` [s] runs."""
        return max(1, math.ceil(duration / self.tick - 1e-9))

    def phase(
        self,
        duration: float,
        arm: Callable[[float], FloatArray],
        hand: Callable[[float], FloatArray],
        grasping: bool,
        after_tick: Callable[[], None] | None = None,
    ) -> bool:
        """Run ``duration`` [s] with the arm's and the closure's targets as functions of the phase time [s] (set
        for the end of each tick: servos lead by one tick), calling ``after_tick`` after each; False if the
        trial ended (:meth:`step`). ``grasping`` as in :meth:`step`."""
        data, scene = self.data, self.scene
        n = self.ticks(duration)
        for k in range(n):
            self.done += 1
            rp = self.replayed
            if rp is not None and self.done <= rp.tick:  # replayed: only the object's rise is recorded
                self.out.max_rise = max(self.out.max_rise, float(rp.heights[self.done - 1]) - self.z0)
                continue
            t = (k + 1) * self.tick
            self.targets = (arm, k, n)
            data.ctrl[scene.arm_actuators] = arm(t)
            data.ctrl[scene.closure_actuators] = hand(t)
            if not self.step(grasping):
                return False
            if after_tick is not None:
                after_tick()
        return True

    def settled(self) -> None:
        """Record how far the object fell before the closure; one that fell more than :data:`SETTLE_DROP` (given
        above the table) has its rise counted from where it came to rest."""
        z = self.object_height()
        self.out.settle_drop = self.z0 - z
        if self.out.settle_drop > SETTLE_DROP:
            self.z0 = z
            self.out.max_rise = 0.0

    def finish(self, ok: bool, p_hold: FloatArray) -> SimOutcome:
        """The outcome, with what the end of the hold shows when the trial ran to it (``ok``) or stopped on the
        ``out_of_reach`` rule (the object on the table, out of the hand, as the end of the hold would show it);
        ``p_hold`` [m] is the object's centre in the flange frame at the start of the hold."""
        scene, data, out = self.scene, self.data, self.out
        out.sim_time = float(data.time)
        if not out.unstable and diverged(data):
            out.unstable = True  # a divergence no tick saw
        if self.alone_end is not None:  # stopped by clear_alone: the end of the schedule is the alone simulation's
            out.rise = self.alone_end.height - self.z0
            out.max_rise = max(out.max_rise, self.alone_end.max_height - self.z0)
            out.touching_table_end = self.alone_end.touches_table
        elif ok or (out.stopped is not None and out.stopped["rule"] == "out_of_reach"):
            contacts = scene.contact_summary(data)
            out.rise = float(scene.object_position(data)[2]) - self.z0
            out.touching_end = contacts.object_hand
            out.touching_table_end = contacts.object_table
        if ok:
            out.slip = float(np.linalg.norm(scene.object_in_flange(data) - p_hold))
        return out


PhaseTargets = tuple[float, Callable[[float], FloatArray], Callable[[float], FloatArray]]
"""A phase's duration [s] and its arm and closure targets as functions of the phase time [s]."""


def _approach_and_closure(scene: Scene, approach: FloatArray, cfg: RolloutConfig) -> tuple[PhaseTargets, PhaseTargets]:
    """The approach (the arm along ``approach``, the hand open) and the closure (the arm at the grasp, the closure
    ramp) of the schedule (module docstring)."""
    closure = scene.hand.manifest.closure
    c_open, q_grasp = scene.closure_open, approach[-1]

    def along(t: float) -> FloatArray:
        return interp(approach, quintic(t / cfg.approach_time))

    def open_hand(_t: float) -> FloatArray:
        return c_open

    def at_grasp(_t: float) -> FloatArray:
        return q_grasp

    def ramp(t: float) -> FloatArray:
        return closure_command(scene.hand, t, closure.duration)

    return (cfg.approach_time, along, open_hand), (closure.duration + closure.settle, at_grasp, ramp)


def record_prefix(scene: Scene, obj: TableObject, approach: FloatArray, cfg: RolloutConfig) -> Prefix:
    """The approach and the closure of ``approach`` simulated with ``obj`` moved :data:`FAR` along world x (out of
    the robot's reach), every tick recorded (:class:`~softsig_service.simulation.approach_replay.Prefix`)."""
    far = np.array(obj.primitive_pose, dtype=np.float64)
    far[0, 3] += FAR
    run = Run(scene, obj, approach[0], cfg, pose=far)
    recorder = PrefixRecorder(scene, run.data)
    n_approach = -1  # not reached: the recording ended before the approach did (a diverged simulation)
    for i, (duration, arm, hand) in enumerate(_approach_and_closure(scene, approach, cfg)):
        if not run.phase(duration, arm, hand, False, recorder.tick):
            break
        if i == 0:
            n_approach = run.done
    return recorder.prefix(n_approach, run.out.arm_collision_time)


def _replayed_start(run: Run, obj: TableObject, approach: FloatArray, cfg: RolloutConfig) -> None:
    """Resume ``run`` where the shared recording of its plan lets it (:mod:`~softsig_service.simulation.
    approach_replay`), or leave it at the start."""
    scene = run.scene
    closure = scene.hand.manifest.closure
    schedule = (run.nsub, cfg.approach_time, cfg.control_period, closure.duration, closure.settle)
    prefix = cached_prefix(scene, schedule, approach, lambda: record_prefix(scene, obj, approach, cfg))
    if prefix.n < 2:
        return
    rp = replay(scene, build_object_alone(obj, scene), run.data, prefix, run.nsub)
    if rp.tick > 0:
        run.resume(prefix, rp)


def _replayed_snapshot(run: Run, name: str) -> dict[str, Any]:
    """The diagnosis snapshot at the end of a replayed approach: the recorded robot with the replayed object."""
    scene, rp, prefix = run.scene, run.replayed, run.prefix
    assert rp is not None and rp.approach_end is not None and prefix is not None
    k, a = prefix.n_approach, scene.object_qpos
    probe = mujoco.MjData(scene.model)
    probe.qpos[:], probe.qvel[:] = prefix.qpos[k], prefix.qvel[k]
    probe.act[:], probe.ctrl[:] = prefix.act[k], prefix.ctrl[k]
    probe.qpos[a : a + 7] = rp.approach_end
    probe.time = float(prefix.time[k])
    mujoco.mj_forward(scene.model, probe)
    return snapshot(scene, probe, name)


def simulate(
    scene: Scene,
    obj: TableObject,
    approach: FloatArray,
    lift: FloatArray,
    cfg: RolloutConfig,
    on_frame: FrameCallback | None,
    frame_period: float,
    on_phase: PhaseObserver | None = None,
) -> SimOutcome:
    """Step the scene through approach, close, lift and hold; record what the judge needs. ``on_phase`` sees the
    start and the end of each phase (:class:`PhaseObserver`)."""
    run = Run(scene, obj, approach[0], cfg)
    data = run.data
    if on_phase is not None:
        on_phase.start(scene, data, (approach[0], approach[-1], lift[-1]))
    if (cfg.replay_approach and on_frame is None and on_phase is None and scene.obstacle_geoms.size == 0
            and scene.object_geoms.size == 1 and not scene.stray_colliders):  # fmt: skip
        _replayed_start(run, obj, approach, cfg)
    c_closed = scene.closure_closed
    next_frame = 0.0

    def frame() -> None:
        nonlocal next_frame
        if on_frame is not None and data.time >= next_frame - 1e-9:
            on_frame(scene, data)
            next_frame += frame_period

    frame()
    q_top = lift[-1]
    (t_approach, along, open_hand), (t_closure, at_grasp, ramp) = _approach_and_closure(scene, approach, cfg)

    def closed_hand(_t: float) -> FloatArray:
        return c_closed

    def phase(
        duration: float, arm: Callable[[float], FloatArray], hand: Callable[[float], FloatArray], grasping: bool
    ) -> bool:
        return run.phase(duration, arm, hand, grasping, frame)

    def seen(name: str) -> None:
        shot = _replayed_snapshot(run, name) if run.in_replay() else snapshot(scene, data, name)
        run.out.phases.append(shot)
        if on_phase is not None:
            on_phase.phase_end(scene, data, run.out.phases[-1])

    ok = phase(t_approach, along, open_hand, False)
    if ok:
        run.settled()
        seen("approach")
    ok = ok and phase(t_closure, at_grasp, ramp, False)
    if ok:
        run.out.touching_after_close = scene.contact_summary(data).object_hand
        seen("closure")

    def at_top(_t: float) -> FloatArray:
        return q_top

    if cfg.hold_time > 0.0:
        run.tail = [(run.ticks(cfg.hold_time), at_top)]
    ok = ok and phase(cfg.lift_time, lambda t: interp(lift, quintic(t / cfg.lift_time)), closed_hand, True)
    run.tail = []
    if ok:
        seen("lift")
    p_hold = scene.object_in_flange(data)  # the object in the hand frame at the start of the hold
    ok = ok and (cfg.hold_time <= 0.0 or phase(cfg.hold_time, at_top, closed_hand, True))
    if ok and cfg.hold_time > 0.0:
        seen("hold")
    if run.out.stopped is not None and run.out.stopped["rule"] in ("out_of_reach", "clear_alone"):
        seen("stopped")
    return run.finish(ok, p_hold)
