"""One validation trial: plan on the nominal object pose, then roll the plan out in MuJoCo and judge it.

Planning: :class:`~softsig_service.planning.planner.Planner` on the *nominal* object pose; a plan that fails
ends the trial with the plan's first reason (``unreachable``, ``collision:table``, ...). The rollout (the
object's perturbation, approach, closure, lift, hold) and the judge: :mod:`softsig_service.simulation.rollout`,
whose docstring lists the reasons. World frame (UR5 ``base_link``, z up), SI units. A trial is deterministic
for a seed.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from softsig_service.arm.trajectory import arm_paths, duration
from softsig_service.arm.ur5 import UR5
from softsig_service.config import Settings
from softsig_service.errors import InvalidInput
from softsig_service.objects import TableObject
from softsig_service.planning.planner import Planner
from softsig_service.planning.request import GraspPlan, PlanRequest
from softsig_service.simulation.rollout import (
    FrameCallback,
    Perturbation,
    PhaseObserver,
    RolloutConfig,
    judge,
    simulate,
)
from softsig_service.simulation.scene import build_scene


@dataclass(frozen=True)
class TrialResult:
    """The outcome of one trial (see the module docstring for the judge and the reasons).

    Attributes:
        seed: the trial's seed (echoed). success: the judge's verdict. reason: None on success, else why.
        lift_height: [m] how far the object's centre rose between the start and the end of the trial
            (0.0 when nothing was simulated).
        max_lift: [m] the largest rise seen at any control tick.
        touching_end: object-hand contact at the end. touching_after_close: object-hand contact at the end
            of the closure.
        touching_table_end: object-table contact at the end (a carried object has none).
        touched_in_lift: object-hand contact at some control tick of the lift or the hold.
        sag: [m] ``lift - lift_height`` at the end of the hold (module docstring); None when the simulation
            did not reach the end (not simulated, or diverged).
        slip: [m] the object's displacement relative to the flange frame during the hold (module
            docstring); None when the simulation did not reach the end.
        perturbation: the drawn object offset. plan_reasons: the planner's reasons (empty: plan feasible).
        sim_time: [s] simulated time. wall_time: [s] wall time of the whole trial (plan + IK + simulation).
        timing: [s] wall time per part: ``plan``, ``ik``, ``sim``.
        arm_collision_time: [s] sim time of the first arm collision (module docstring; None: none).
        settle_drop: [m] how far the object fell before the hand closed: above
            :data:`~softsig_service.simulation.rollout.SETTLE_DROP`, it was given above the table and settled
            (its lift is counted from where it came to rest); None when the approach was not simulated to its end.
    """

    seed: int
    success: bool
    reason: str | None
    lift_height: float
    max_lift: float
    touching_end: bool
    touching_after_close: bool
    perturbation: Perturbation
    hand: str
    object: str
    strategy: str
    sigma_r: float
    sigma_t: float
    plan_reasons: list[str]
    sim_time: float
    wall_time: float
    timing: dict[str, float] = field(default_factory=dict)
    arm_collision_time: float | None = None
    touching_table_end: bool = False
    touched_in_lift: bool = False
    sag: float | None = None
    slip: float | None = None
    settle_drop: float | None = None
    diagnosis: dict[str, Any] = field(default_factory=dict)
    """Why the trial ended as it did (:mod:`softsig_service.simulation.diagnosis`): ``phases``, a snapshot at the
    end of each phase run, and ``released_at`` [s]; empty when nothing was simulated."""

    def to_json_dict(self) -> dict[str, Any]:
        """A flat JSON record (units: m, rad, s); the perturbation as ``{"d_yaw", "dx", "dy"}``."""
        return dataclasses.asdict(self)


_PLANNERS: OrderedDict[Settings | None, Planner] = OrderedDict()
_PLANNERS_LOCK = threading.Lock()
MAX_PLANNERS = 4
"""Planners a process keeps (one per distinct settings, least recently used dropped first)."""


def default_planner(settings: Settings | None = None) -> Planner:
    """One :class:`Planner` per process and settings value (its UR5 and collision worlds are built once): equal
    settings, such as the copy a worker process receives, share it."""
    with _PLANNERS_LOCK:
        planner = _PLANNERS.get(settings)
        if planner is None:
            planner = _PLANNERS[settings] = Planner(settings)
            while len(_PLANNERS) > MAX_PLANNERS:
                _PLANNERS.popitem(last=False)
        _PLANNERS.move_to_end(settings)
        return planner


def run_trial(
    hand: str,
    obj: TableObject,
    strategy: Literal["S", "C", "R"],
    *,
    seed: int,
    sigma_r: float = 0.0,
    sigma_t: float = 0.0,
    config: RolloutConfig | None = None,
    planner: Planner | None = None,
    settings: Settings | None = None,
    plan: GraspPlan | None = None,
    on_frame: FrameCallback | None = None,
    frame_period: float = 1.0 / 30.0,
    on_phase: PhaseObserver | None = None,
    plan_options: Mapping[str, Any] | None = None,
    perturbation: Perturbation | None = None,
    obstacles: Sequence[TableObject] = (),
) -> TrialResult:
    """Run one trial (module docstring) of ``hand`` grasping ``obj`` (its nominal pose) with ``strategy``.

    ``sigma_r`` [rad] and ``sigma_t`` [m] are the standard deviations of the object's yaw and x, y offsets;
    ``seed`` seeds them. ``plan`` skips planning (a plan for the same hand, object and strategy, e.g. to test
    a moved plan). ``on_frame`` is called every ``frame_period`` [s] of sim time (videos, frames); ``on_phase`` at
    the start and at the end of each phase (keyframes, :class:`~softsig_service.simulation.rollout.PhaseObserver`).
    ``plan_options`` are further :class:`PlanRequest` fields (``cs_method``, ``cs_criterion``, ``placement``,
    ``capture``...); strategy R plans for ``sigma_r`` and ``sigma_t``. ``perturbation`` moves the simulated object
    by a given offset instead of one drawn from ``seed`` and the sigmas (the capture model's simulations).
    ``obstacles``: other objects on the table, planned around and simulated as free bodies that can be pushed (they
    are not perturbed).
    Raises :class:`InvalidInput` for negative sigmas; never for an infeasible plan or a failed grasp.
    """
    t_wall = time.perf_counter()
    cfg = config or RolloutConfig()
    for name, v in (("sigma_r", sigma_r), ("sigma_t", sigma_t)):
        if not (math.isfinite(v) and v >= 0.0):
            raise InvalidInput("must be a finite number >= 0", field=name, value=v)
    planner = planner or default_planner(settings)
    pert = perturbation if perturbation is not None else Perturbation.draw(seed, sigma_r, sigma_t)
    common: dict[str, Any] = {
        "seed": seed,
        "perturbation": pert,
        "object": obj.name or obj.kind,
        "strategy": strategy,
        "sigma_r": sigma_r,
        "sigma_t": sigma_t,
    }

    t0 = time.perf_counter()
    if plan is None:
        options = dict(plan_options or {})
        if strategy == "R":
            options.setdefault("sigma_r", sigma_r)
            options.setdefault("sigma_t", sigma_t)
        plan = planner.plan(PlanRequest(hand=hand, obj=obj, strategy=strategy, obstacles=tuple(obstacles), **options))
    t_plan = time.perf_counter() - t0

    def early(reason: str, timing: dict[str, float]) -> TrialResult:
        return TrialResult(
            success=False,
            reason=reason,
            lift_height=0.0,
            max_lift=0.0,
            touching_end=False,
            touching_after_close=False,
            hand=plan.hand,
            plan_reasons=list(plan.reasons),
            sim_time=0.0,
            wall_time=time.perf_counter() - t_wall,
            timing=timing,
            **common,
        )

    if not plan.success:
        return early(plan.reasons[0] if plan.reasons else "unreachable", {"plan": t_plan})
    assert plan.grasp_pose is not None and plan.pre_grasp_pose is not None
    assert plan.joint_positions is not None and plan.pre_grasp_joint_positions is not None

    t0 = time.perf_counter()
    ur5 = planner.ur5
    T_grasp = np.asarray(plan.grasp_pose, dtype=np.float64)
    T_pre = np.asarray(plan.pre_grasp_pose, dtype=np.float64)
    q_pre = np.asarray(plan.pre_grasp_joint_positions, dtype=np.float64)
    paths = arm_paths(ur5, T_pre, T_grasp, q_pre, cfg.lift, cfg.waypoints)
    if isinstance(paths, str):
        return early(paths, {"plan": t_plan, "ik": time.perf_counter() - t0})
    approach, lift = paths
    cfg = dataclasses.replace(  # the plan's trajectories' durations (one source: softsig_service.arm.trajectory)
        cfg, approach_time=duration(approach, cfg.approach_time, ur5.velocity_limit),
        lift_time=duration(lift, cfg.lift_time, ur5.velocity_limit),
    )  # fmt: skip
    t_ik = time.perf_counter() - t0

    t0 = time.perf_counter()
    scene = build_scene(hand, obj, settings or planner.settings, obstacles)
    sim = simulate(scene, pert.apply(obj), approach, lift, cfg, on_frame, frame_period, on_phase)
    t_sim = time.perf_counter() - t0

    reason = judge(sim, cfg)
    return TrialResult(
        success=reason is None,
        reason=reason,
        lift_height=sim.rise,
        max_lift=sim.max_rise,
        touching_end=sim.touching_end,
        touching_after_close=sim.touching_after_close,
        hand=plan.hand,
        plan_reasons=[],
        sim_time=sim.sim_time,
        wall_time=time.perf_counter() - t_wall,
        timing={"plan": t_plan, "ik": t_ik, "sim": t_sim},
        arm_collision_time=sim.arm_collision_time,
        touching_table_end=sim.touching_table_end,
        touched_in_lift=sim.touched_in_lift,
        sag=None if sim.unstable else cfg.lift - sim.rise,
        slip=sim.slip,
        settle_drop=sim.settle_drop,
        diagnosis={"phases": sim.phases, "released_at": sim.released_at, "stopped": sim.stopped},
        **common,
    )


def shift_plan(plan: GraspPlan, offset: NDArray[np.float64], ur5: UR5) -> GraspPlan:
    """``plan`` with its grasp and pre-grasp flange poses moved by ``offset`` (3,) [m] in the world frame and
    the joint positions re-solved by IK (seeded by the plan's). For tests and diagnostics: the planner's
    collision checks are *not* repeated. An unreachable moved pose gives ``success=False`` with reason
    ``unreachable``."""
    if not plan.success or plan.grasp_pose is None or plan.pre_grasp_pose is None:
        return plan
    assert plan.joint_positions is not None
    d = np.asarray(offset, dtype=np.float64).reshape(3)
    T = np.asarray(plan.grasp_pose, dtype=np.float64).copy()
    T_pre = np.asarray(plan.pre_grasp_pose, dtype=np.float64).copy()
    T[:3, 3] += d
    T_pre[:3, 3] += d
    ik = ur5.solve_ik(T, np.asarray(plan.joint_positions))
    ik_pre = ur5.solve_ik(T_pre, ik.q) if ik.success else ik
    ok = ik.success and ik_pre.success
    return dataclasses.replace(
        plan,
        success=ok,
        reasons=[] if ok else ["unreachable"],
        grasp_pose=T,
        pre_grasp_pose=T_pre,
        joint_positions=ik.q.tolist() if ok else None,
        pre_grasp_joint_positions=ik_pre.q.tolist() if ok else None,
    )
