"""Top-grasp planning: strategy -> wrist pose -> descent along the approach -> UR5 IK -> collision checks.

Frames: world = UR5 ``base_link`` (z up); poses are of the flange ``tool0`` (= the hand frame). A top grasp
points hand +z (the approach) down. The planner:

1. proposes the flange orientation and horizontal position of both yaw branches: strategy **S** aligns hand +x
   with the object's major axis; strategy **C** solves the wrist-pose NLP that aligns the closure signature's
   horizontal projection with the object's closing axis (default the minor axis). Both put the same point of
   the hand over the object's centre, so that S and C differ only in yaw (docs/design.md §6): by default
   (``placement="open_centre"``) the centre c_0 of the open hand's reference-point ellipsoid (the ellipsoid
   CS's anchor); ``placement="grasp_centre"`` the centre c_T of the closed hand's reference-point ellipsoid
   (docs/design.md §6's grasp centre; for the SoftHand it lies under the palm, where a top grasp cannot wrap an
   object: docs/experiment_table1.md); ``placement="per_strategy"`` keeps the earlier per-strategy rule (S: centre
   of the open reference points' bounding box, C: the CS anchor) for ablations;
2. descends from high above along the approach until the open hand comes within ``margin`` of the table or the
   object (the grasp pose), and raises the pre-grasp ``approach_distance`` back along the approach;
3. solves the UR5 IK for the grasp (seeded by the current configuration) and the pre-grasp (seeded by the grasp),
   and the joint paths of the approach and the lift exactly as the validation executes them
   (:func:`~softsig_service.arm.trajectory.arm_paths`); checks arm + hand against table, object and itself at
   every approach waypoint (coal), except the hand's pairs with table and object where the descent has shown the
   whole approach clear of them (:meth:`Planner._place`), and the arm links against table and themselves along
   the lift;
4. returns, of the feasible branches, the one whose grasp configuration is closest to the current one.
   An infeasible request gives ``success=False`` with machine-readable ``reasons``.

With ``candidates = k > 1`` it also offers the alternatives of :mod:`softsig_service.planning.ranking` (the other
closing axis, placements shifted along the object's major axis, both yaw branches), estimates each one's
``grasp_quality``, and checks them best first (quality, then the strategy's own pose, then the joint distance
from the current configuration) until ``k`` distinct ones pass every check: ``grasps``, best first, the plan's
top-level fields describing the first. With ``k = 1`` the plan is the one described above, its one grasp ranked
with its quality.
"""

from __future__ import annotations

import math
import threading
import time
import weakref
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from softsig_service.arm.collision import CollisionWorld
from softsig_service.arm.trajectory import (
    APPROACH_TIME,
    LIFT,
    LIFT_TIME,
    MAX_JOINT_STEP,
    arm_paths,
    duration,
    timed,
)
from softsig_service.arm.ur5 import HOME_Q, POSITION_TOLERANCE, ROTATION_TOLERANCE, UR5, load_ur5
from softsig_service.config import Settings
from softsig_service.objects import TableObject
from softsig_service.planning.clearance import HandClearance, HandGeometry
from softsig_service.planning.hand_model import (
    HandPlanningModel,
    planning_model,
)
from softsig_service.planning.ranking import alternatives, grasp_quality
from softsig_service.planning.request import GraspPlan, PlanRequest
from softsig_service.planning.strategies import axis_angle_between_lines, relative_poses, strategy_s_poses
from softsig_service.planning.strategy_r import c_relative_theta, solve_strategy_r
from softsig_service.planning.wrist_nlp import solve_joint_wrist
from softsig_service.planning.wrist_pose import solve_wrist_pose_unchecked

START_HEIGHT = 0.5
"""[m] the descent starts this far above the object's centre along the approach."""
WORLDS_PER_MODEL = 8
"""Collision worlds (one per table height) a thread keeps per hand model."""
GJK_SLACK = 1e-6
"""[m] what coal's distances may be off by (its GJK tolerance)."""


@dataclass(eq=False)
class _Candidate:
    T: NDArray[np.float64]
    status: str
    iterations: int
    reasons: list[str] = field(default_factory=list)
    q: NDArray[np.float64] | None = None
    q_pre: NDArray[np.float64] | None = None
    T_pre: NDArray[np.float64] | None = None
    ik_residual: float | None = None
    clearance: float | None = None
    joint_distance: float = math.inf
    """[rad] the grasp configuration's Euclidean distance from the current one in joint space."""
    approach_clear: bool = False
    """The descent showed the hand clear of table and object all along the approach (see ``Planner._place``)."""
    primary: bool = True
    """The strategy's own pose (else an alternative of :mod:`softsig_service.planning.ranking`)."""
    label: str = ""
    quality: float = 0.0
    quality_model: str = ""
    approach_path: NDArray[np.float64] | None = None
    """Joint paths (waypoints, 6) [rad] of the approach and the lift (:mod:`softsig_service.arm.trajectory`)."""
    lift_path: NDArray[np.float64] | None = None
    grasp_in_flange: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    """``T_HG``: the hand's grasp frame in the flange frame. ``T`` and ``T_pre`` are grasp-frame poses; the arm's
    IK and the paths use :attr:`flange` and :attr:`flange_pre`."""

    @property
    def flange(self) -> NDArray[np.float64]:
        """The flange pose (4x4, world) of the grasp-frame pose ``T``."""
        return np.asarray(self.T @ np.linalg.inv(self.grasp_in_flange), dtype=np.float64)

    @property
    def flange_pre(self) -> NDArray[np.float64]:
        """The flange pose (4x4, world) of the pre-grasp ``T_pre``."""
        assert self.T_pre is not None
        return np.asarray(self.T_pre @ np.linalg.inv(self.grasp_in_flange), dtype=np.float64)


class Planner:
    """Plans top grasps for a UR5; models and collision worlds are built once and reused.

    Thread-safe without a planner-wide lock: the mutable state is per thread (each thread has its own collision
    worlds, Pinocchio data and compiled wrist-pose solvers); the hand geometry is shared read-only.
    """

    def __init__(self, settings: Settings | None = None, ur5: UR5 | None = None) -> None:
        self.settings = settings
        self.ur5 = ur5 or load_ur5(settings.robots_dir if settings is not None else None)
        self._local = threading.local()
        self._hands: weakref.WeakKeyDictionary[HandPlanningModel, HandGeometry] = weakref.WeakKeyDictionary()
        self._hands_lock = threading.Lock()

    def _world(self, model: HandPlanningModel, table_height: float, purpose: str = "worlds") -> CollisionWorld:
        """This thread's collision world for the hand ``model`` over a table at ``table_height`` [m]; ``purpose``
        keeps apart worlds that hold other objects (``"obstacle_worlds"``: one obstacle at a time).

        Keyed by the model itself (weakly: a model the planning-model cache has let go takes its worlds with it),
        so a replaced hand's new model never meets its old geometry; at most ``WORLDS_PER_MODEL`` table heights
        per model and thread (least recently used first out)."""
        worlds: weakref.WeakKeyDictionary[HandPlanningModel, dict[float, CollisionWorld]] | None = getattr(
            self._local, purpose, None
        )
        if worlds is None:
            worlds = weakref.WeakKeyDictionary()
            setattr(self._local, purpose, worlds)
        by_height = worlds.get(model)
        if by_height is None:
            by_height = worlds[model] = {}
        key = round(table_height, 6)
        world = by_height.pop(key, None)
        if world is None:
            world = CollisionWorld(self.ur5, model.flange_shapes or model.shapes, table_height=table_height)
            while len(by_height) >= WORLDS_PER_MODEL:
                del by_height[next(iter(by_height))]
        by_height[key] = world  # re-inserted: the dict's order is the order of use
        return world

    def _hand(self, model: HandPlanningModel) -> HandGeometry:
        """The hand's clearance geometry, built once per hand and shared by every thread."""
        hand = self._hands.get(model)
        if hand is None:
            with self._hands_lock:
                hand = self._hands.setdefault(model, HandGeometry(model.shapes))
        return hand

    def plan(self, req: PlanRequest) -> GraspPlan:
        """Plan ``req``; never raises for an infeasible problem (``success=False`` with reasons)."""
        t_start = time.perf_counter()
        model = planning_model(req.hand, req.cs_method, self.settings, req.cs_criterion, req.hand_revision)
        obj = req.obj
        q_now = np.asarray(req.current_q if req.current_q is not None else HOME_Q, dtype=float)
        closing = obj.o2 if req.closing_axis == "minor" else obj.o1
        center = obj.center
        hand_point = model.placement_point(req.strategy, req.placement)

        t0 = time.perf_counter()
        candidates: list[_Candidate] = []
        expected_capture: float | None = None
        theta_r: float | None = None
        if req.strategy == "C" and req.relative_pose is None:
            sols = solve_wrist_pose_unchecked(
                model.signature.axis, hand_point, model.points_open, center, closing, obj.table_height, req.margin
            )
            for s in sols:
                c = _Candidate(T=s.T_world_hand, status=s.status, iterations=s.iterations)
                if not s.success:
                    c.reasons.append("alignment_impossible" if s.status == "alignment_impossible" else "unreachable")
                candidates.append(c)
        elif req.relative_pose is not None:
            for T in relative_poses(center, obj.o1, hand_point, *req.relative_pose):
                candidates.append(_Candidate(T=T, status="relative_pose", iterations=0))
        elif req.strategy == "R":
            assert req.capture is not None
            theta_c = c_relative_theta(model.signature.axis, req.closing_axis)
            choice = solve_strategy_r(req.capture, req.sigma_r, req.sigma_t, theta_c)
            expected_capture = choice.expected
            theta_r = choice.theta
            for T in relative_poses(center, obj.o1, hand_point, choice.theta, choice.u, choice.v):
                candidates.append(_Candidate(T=T, status=f"r:{choice.status}", iterations=choice.iterations))
        else:
            for T in strategy_s_poses(center, obj.o1, hand_point):
                candidates.append(_Candidate(T=T, status="closed_form", iterations=0))
        for i, c in enumerate(candidates):
            c.label = f"{req.strategy}:branch={i}"
        if req.candidates > 1 and req.relative_pose is None:
            candidates += self._alternatives(req, model, hand_point, closing_theta(req, model, theta_r))
        for c in candidates:
            c.grasp_in_flange = model.grasp_in_flange
        t_strategy = time.perf_counter() - t0

        t_ik = t_col = 0.0
        world = self._world(model, obj.table_height)
        world.set_object_unchecked(obj.primitive(), obj.primitive_pose)
        clearance = HandClearance(model.shapes, obj, obj.table_height, self._hand(model), world.placed_object)
        quality_point = model.placement_point("R", req.placement)  # the capture model's relative poses
        for c in candidates:
            c.quality, c.quality_model = grasp_quality(
                c.T, model.signature.axis, quality_point, obj, req.capture, req.sigma_r, req.sigma_t
            )
        # groups in rank order: the strategy's poses alone (k = 1), or best quality first, the strategy's poses
        # first among equals (k > 1); within a group the joint distance from the current configuration decides,
        # so a group is placed and solved only when the groups before it left places to fill
        groups: dict[tuple[float, bool], list[_Candidate]] = {}
        for c in candidates:
            if c.reasons:
                continue
            key = (0.0, True) if req.candidates == 1 else (-round(c.quality, 9), not c.primary)
            groups.setdefault(key, []).append(c)
        ranked: list[_Candidate] = []
        for key in sorted(groups):
            group = groups[key]
            for c in group:
                t1 = time.perf_counter()
                self._place(c, clearance, req, center)
                t2 = time.perf_counter()
                t_col += t2 - t1
                if not c.reasons:
                    self._solve_grasp(c, q_now)
                t_ik += time.perf_counter() - t2
            for c in sorted((c for c in group if not c.reasons), key=lambda c: c.joint_distance):
                if any(_same_grasp(c, r) for r in ranked):
                    continue
                dt_ik, dt_col = self._finish(c, req, world)
                t_ik, t_col = t_ik + dt_ik, t_col + dt_col
                if not c.reasons:
                    ranked.append(c)
                    if len(ranked) == req.candidates:
                        break
            if len(ranked) == req.candidates:
                break

        up, closing_3d = _object_axes(obj, req.closing_axis)
        tilted = float(up[2]) < math.cos(TILTED)
        impossible = any("alignment_impossible" in c.reasons for c in candidates)
        if req.strategy == "C" and req.relative_pose is None and (tilted or not ranked) and not impossible:
            # a tilted object, or no closed-form pose passed: the NLP over the arm's joints (exact reach and
            # limits, the wrist tilted within the approach cone), its pose checked as every other, first
            t1 = time.perf_counter()
            joint = self._joint_candidate(req, model, hand_point, closing_3d, up, clearance, q_now)
            t_strategy += time.perf_counter() - t1
            if joint is not None:
                joint.quality, joint.quality_model = grasp_quality(
                    joint.T, model.signature.axis, quality_point, obj, req.capture, req.sigma_r, req.sigma_t
                )
                candidates.append(joint)
                if not joint.reasons:
                    dt_ik, dt_col = self._finish(joint, req, world)
                    t_ik, t_col = t_ik + dt_ik, t_col + dt_col
                    if not joint.reasons:
                        ranked = [joint, *(r for r in ranked if not _same_grasp(r, joint))][: req.candidates]
            if tilted:
                closing = closing_3d

        feasible = ranked
        best = ranked[0] if ranked else _most_advanced(candidates)
        R = best.T[:3, :3]
        if req.strategy in ("C", "R"):
            align = axis_angle_between_lines(R @ model.signature.axis, closing)
        else:
            align = axis_angle_between_lines(R[:, 0], obj.o1)
        approach_dir = R[:, 2]
        ok = any(best is c for c in feasible)
        return GraspPlan(
            success=ok,
            reasons=[] if ok else sorted(set(best.reasons), key=best.reasons.index),
            strategy=req.strategy,
            hand=model.name,
            object=obj.to_json(),
            joint_names=list(self.ur5.joint_names),
            joint_positions=best.q.tolist() if ok and best.q is not None else None,
            pre_grasp_joint_positions=best.q_pre.tolist() if ok and best.q_pre is not None else None,
            grasp_pose=best.flange,
            pre_grasp_pose=best.flange_pre if best.T_pre is not None else None,
            grasp_frame_pose=best.T,
            approach={
                "direction": approach_dir.tolist(),
                "frame_id": "base_link",
                "desired_distance": req.approach_distance,
                "min_distance": 0.5 * req.approach_distance,
                "retreat_distance": LIFT,
            },
            quality={
                "alignment_error": align,
                "ik_residual": best.ik_residual,
                "clearance": best.clearance,
                "expected_capture": expected_capture,
            },
            timing={
                "strategy": t_strategy,
                "ik": t_ik,
                "collision": t_col,
                "total": time.perf_counter() - t_start,
            },
            closure=model.closure,
            grasps=[_grasp_json(c, rank, self.ur5) for rank, c in enumerate(ranked)],
            solver={
                "status": best.status,
                "iterations": best.iterations,
                "cs_method": req.cs_method,
                "cs_criterion": req.cs_criterion,
                "placement": req.placement,
            },
        )

    def _joint_candidate(
        self,
        req: PlanRequest,
        model: HandPlanningModel,
        hand_point: NDArray[np.float64],
        closing: NDArray[np.float64],
        up: NDArray[np.float64],
        clearance: HandClearance,
        q_now: NDArray[np.float64],
    ) -> _Candidate | None:
        """C's pose from the NLP over the arm's joints (:mod:`softsig_service.planning.wrist_nlp`), placed by the
        descent and solved by IK from the NLP's joints; None when the NLP finds no aligned, centred pose. Its depth
        target is the untilted pose's: the descent's stand-off of the placement point before the object's centre."""
        obj = req.obj
        theta = c_relative_theta(model.signature.axis, req.closing_axis)
        vertical = _Candidate(T=relative_poses(obj.center, obj.o1, hand_point, theta, 0.0, 0.0)[0], status="",
                              iterations=0, grasp_in_flange=model.grasp_in_flange)  # fmt: skip
        self._place(vertical, clearance, req, obj.center)
        p = vertical.T[:3, :3] @ hand_point + vertical.T[:3, 3]
        stand_off = float((obj.center - p) @ vertical.T[:3, 2])
        sol = solve_joint_wrist(
            self.ur5, q_now, model.grasp_in_flange, model.signature.axis, hand_point, model.points_open, obj.center,
            closing, up, obj.table_height, req.margin, cone=req.approach_cone,
            stand_off=stand_off, approach_distance=req.approach_distance, lift=LIFT,
        )  # fmt: skip
        if not sol.success:
            return None
        c = _Candidate(T=sol.T_world_grasp, status=f"joint_nlp:{sol.status}", iterations=sol.iterations,
                       label="C:joint_nlp", grasp_in_flange=model.grasp_in_flange)  # fmt: skip
        self._place(c, clearance, req, obj.center)
        if not c.reasons:
            self._solve_grasp(c, sol.q)
            if not c.reasons:
                dq = c.q - q_now  # type: ignore[operator]
                c.joint_distance = math.sqrt(float(dq @ dq))
        return c

    def _alternatives(
        self, req: PlanRequest, model: HandPlanningModel, hand_point: NDArray[np.float64], thetas: tuple[float, float]
    ) -> list[_Candidate]:
        """The non-primary candidates of :func:`~softsig_service.planning.ranking.alternatives` (the primary ones
        are the strategy's own poses, already proposed)."""
        return [
            _Candidate(T=a.T, status="alternative", iterations=0, primary=False, label=a.label)
            for a in alternatives(req.obj, hand_point, *thetas)
            if not a.primary
        ]

    def _finish(self, c: _Candidate, req: PlanRequest, world: CollisionWorld) -> tuple[float, float]:
        """Pre-grasp IK, the approach and lift paths the validation executes (:mod:`softsig_service.arm.trajectory`)
        and their collision checks, for a candidate with a grasp IK solution.

        Returns (IK time, collision time) [s].
        """
        t0 = time.perf_counter()
        paths = self._paths(c)
        t1 = time.perf_counter()
        if paths is not None:
            approach, lift = paths
            self._check(c, world, approach, lift)
            if not c.reasons and req.obstacles:
                self._check_obstacles(c, req, np.vstack([approach, lift[1:]]))
        return t1 - t0, time.perf_counter() - t1

    def _check_obstacles(self, c: _Candidate, req: PlanRequest, path: NDArray[np.float64]) -> None:
        """Every arm link and hand shape against each obstacle, along the whole approach, at the grasp and along
        the lift, with the plan's margin [m]: the hand may touch its target, never an obstacle."""
        model = planning_model(req.hand, req.cs_method, self.settings, req.cs_criterion, req.hand_revision)
        world = self._world(model, req.obj.table_height, "obstacle_worlds")
        Q = np.asarray(path)
        for i, obstacle in enumerate(req.obstacles):
            world.set_object_unchecked(obstacle.primitive(), obstacle.primitive_pose)
            report = world.check_waypoints(Q, margin=req.margin, check_table=False, check_self=False, distances=False)
            if report.in_collision:
                c.reasons.append(f"collision:obstacle[{i}]")

    def check_wrist_pose(self, req: PlanRequest, T_grasp: NDArray[np.float64]) -> list[str]:
        """Reasons why the grasp flange pose ``T_grasp`` (4x4, world) fails for ``req`` (empty: feasible).

        Runs the same IK, approach and collision checks as :meth:`plan` on a pose given by the caller.
        """
        model = planning_model(req.hand, req.cs_method, self.settings, req.cs_criterion, req.hand_revision)
        q_now = np.asarray(req.current_q or HOME_Q, dtype=float)
        T_g = np.asarray(T_grasp, dtype=float) @ model.grasp_in_flange  # the grasp frame's pose
        c = _Candidate(T=T_g, status="given", iterations=0, grasp_in_flange=model.grasp_in_flange)
        c.T_pre = c.T.copy()
        c.T_pre[:3, 3] -= c.T[:3, 2] * req.approach_distance
        world = self._world(model, req.obj.table_height)
        world.set_object_unchecked(req.obj.primitive(), req.obj.primitive_pose)
        self._solve_grasp(c, q_now)
        if not c.reasons:
            self._finish(c, req, world)
        return c.reasons

    def _place(self, c: _Candidate, clearance: HandClearance, req: PlanRequest, center: NDArray[np.float64]) -> None:
        """Descend along the approach from high above to the grasp pose; set the pre-grasp.

        The descent advances conservatively, so every pose it passed keeps the hand ``margin`` [m] clear of table
        and object. When the pre-grasp lies on that stretch, so does the whole straight approach, and the
        approach's arm configurations need not check the hand's pairs with table and object again
        (``approach_clear``), provided the margin exceeds what the IK may leave (its position tolerance, and its
        rotation tolerance times the hand's reach from the flange) and coal's own tolerance."""
        direction = c.T[:3, 2]
        T_top = c.T.copy()
        T_top[:3, 3] -= direction * ((c.T[:3, 3] - center) @ direction + START_HEIGHT)
        d0 = clearance.nearest(T_top)[0]
        if d0 < req.margin:
            c.reasons.append("collision:object")  # even the start above the object is blocked
            return
        descent = clearance.descend(T_top, direction, max_travel=START_HEIGHT + 0.5, margin=req.margin)
        c.T = descent.T_world_hand
        c.clearance = descent.distance
        c.T_pre = c.T.copy()
        c.T_pre[:3, 3] -= direction * req.approach_distance
        ik_slack = POSITION_TOLERANCE + ROTATION_TOLERANCE * clearance.extent
        c.approach_clear = descent.travel >= req.approach_distance and req.margin > ik_slack + GJK_SLACK

    def _solve_grasp(self, c: _Candidate, q_now: NDArray[np.float64]) -> None:
        ik = self.ur5.solve_ik_unchecked(c.flange, q_now)
        if not ik.success:
            c.reasons.append("unreachable")
            return
        c.q = ik.q
        c.ik_residual = ik.position_residual
        dq = ik.q - q_now
        c.joint_distance = math.sqrt(float(dq @ dq))

    def _paths(self, c: _Candidate) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The pre-grasp IK (seeded by the grasp's) and the joint paths of the approach (pre-grasp to grasp) and the
        lift (:func:`~softsig_service.arm.trajectory.arm_paths`); None (with the reason) where one is unreachable or
        the approach ends on another IK branch than the grasp's solution. The grasp's joints become the approach's
        last point (the configuration the arm arrives in)."""
        assert c.q is not None and c.T_pre is not None
        pre = self.ur5.solve_ik_unchecked(c.flange_pre, c.q)
        if not pre.success:
            c.reasons.append("unreachable:pre_grasp")
            return None
        c.q_pre = pre.q
        c.ik_residual = max(c.ik_residual or 0.0, pre.position_residual)
        paths = arm_paths(self.ur5, c.flange_pre, c.flange, pre.q)
        if isinstance(paths, str):
            c.reasons.append(paths)
            return None
        approach, lift = paths
        if float(np.max(np.abs(approach[-1] - c.q))) > MAX_JOINT_STEP:
            c.reasons.append("unreachable:approach")  # a branch flip: the arm would not arrive in the grasp's branch
            return None
        c.q = approach[-1]
        c.approach_path, c.lift_path = approach, lift
        return approach, lift

    def _check(
        self, c: _Candidate, world: CollisionWorld, approach: NDArray[np.float64], lift: NDArray[np.float64]
    ) -> None:
        """Arm and hand along the approach (the hand's pairs with table and object left out where the descent showed
        them clear); then arm links against the table and themselves along the lift (the hand holds the object,
        which rises with it)."""
        report = world.check_waypoints(
            approach, distances=False, ignore_hand_object=c.approach_clear, ignore_hand_table=c.approach_clear
        )
        if not report.in_collision:
            report = world.check_waypoints(
                lift[1:], distances=False, ignore_hand_object=True, ignore_hand_table=True, check_object=False
            )
        if report.in_collision:
            c.reasons.extend(report.reasons)


def closing_theta(req: PlanRequest, model: HandPlanningModel, theta_r: float | None) -> tuple[float, float]:
    """The strategy's relative yaw [rad] (:func:`~softsig_service.planning.strategies.relative_poses`) and the one
    that closes across the object's other axis: S puts hand +x along the major axis (0) or the minor one; C and R
    close the closure signature across the requested axis or the other one (R: its chosen yaw, turned a quarter)."""
    if req.strategy == "S":
        return 0.0, math.pi / 2
    if req.strategy == "R" and theta_r is not None:
        return theta_r, theta_r + math.pi / 2
    other = "major" if req.closing_axis == "minor" else "minor"
    return c_relative_theta(model.signature.axis, req.closing_axis), c_relative_theta(model.signature.axis, other)


TILTED = 1e-3
"""[rad] an object whose own up axis is further than this from vertical is planned tilted (strategy C)."""


def _object_axes(obj: TableObject, closing_axis: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The object's up axis and its closing axis (the minor or major one) in base_link: its own axes when it was
    given turned, else world +z and its horizontal axes."""
    if obj.own_axes is not None:
        A = obj.own_axes
        return A[:, 2], A[:, 1] if closing_axis == "minor" else A[:, 0]
    return np.array([0.0, 0.0, 1.0]), obj.o2 if closing_axis == "minor" else obj.o1


SAME_POSITION = 1e-3
"""[m] two grasps whose flange positions are this close ..."""
SAME_ANGLE = math.radians(1.0)
"""[rad] ... and whose orientations are this close are the same grasp (one is left out of the ranking)."""


def _same_grasp(a: _Candidate, b: _Candidate) -> bool:
    if float(np.linalg.norm(a.T[:3, 3] - b.T[:3, 3])) > SAME_POSITION:
        return False
    cos = (float(np.trace(a.T[:3, :3].T @ b.T[:3, :3])) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, cos))) <= SAME_ANGLE


def _grasp_json(c: _Candidate, rank: int, ur5: UR5) -> dict[str, object]:
    """One ranked grasp (flange poses 4x4 in base_link, joints [rad], its timed approach and lift as joint
    trajectories); :class:`GraspPlan` turns it into JSON."""
    assert c.q is not None and c.q_pre is not None and c.T_pre is not None
    assert c.approach_path is not None and c.lift_path is not None
    return {
        "rank": rank + 1,
        "label": c.label,
        "primary": c.primary,
        "grasp_quality": c.quality,
        "quality_model": c.quality_model,
        "grasp_pose": c.flange,
        "pre_grasp_pose": c.flange_pre,
        "grasp_frame_pose": c.T.copy(),
        "joint_positions": c.q.tolist(),
        "pre_grasp_joint_positions": c.q_pre.tolist(),
        "clearance": c.clearance,
        "ik_residual": c.ik_residual,
        "approach_trajectory": _timed(c.approach_path, APPROACH_TIME, ur5),
        "retreat_trajectory": _timed(c.lift_path, LIFT_TIME, ur5),
    }


def _timed(path: NDArray[np.float64], nominal: float, ur5: UR5) -> dict[str, object]:
    """A joint path timed as the validation executes it (:func:`~softsig_service.arm.trajectory.timed`), in the
    form of trajectory_msgs/JointTrajectory (``time_from_start`` [s] as a number here)."""
    total = duration(path, nominal, ur5.velocity_limit)
    times, velocities = timed(path, total)
    return {
        "joint_names": list(ur5.joint_names),
        "positions": path.tolist(),
        "velocities": velocities.tolist(),
        "time_from_start": times,
        "duration": total,
    }


def _most_advanced(candidates: list[_Candidate]) -> _Candidate:
    """The failed candidate that got furthest (for its reasons and poses)."""
    order = {"alignment_impossible": 0, "unreachable": 1, "unreachable:pre_grasp": 2, "unreachable:approach": 3}
    return max(candidates, key=lambda c: min((order.get(r, 4) for r in c.reasons), default=5))
