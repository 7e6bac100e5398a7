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
   object: docs/experiment_table1.md); ``placement="previous"`` keeps the earlier per-strategy rule (S: centre
   of the open reference points' bounding box, C: the CS anchor) for ablations;
2. descends from high above along the approach until the open hand comes within ``margin`` of the table or the
   object (the grasp pose), and raises the pre-grasp ``approach_distance`` back along the approach;
3. solves the UR5 IK for the grasp (seeded by the current configuration), the pre-grasp (seeded by the grasp)
   and waypoints of the straight approach between them; checks arm + hand against table, object and itself
   at every one of them (coal), except the hand's pairs with table and object where the descent has shown the
   whole approach clear of them (:meth:`Planner._place`);
4. returns, of the feasible branches, the one whose grasp configuration is closest to the current one.
   An infeasible request gives ``success=False`` with machine-readable ``reasons``.
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
from softsig_service.arm.ur5 import HOME_Q, POSITION_TOLERANCE, ROTATION_TOLERANCE, UR5, load_ur5
from softsig_service.config import Settings
from softsig_service.planning.clearance import HandClearance, HandGeometry
from softsig_service.planning.hand_model import (
    HandPlanningModel,
    planning_model,
)
from softsig_service.planning.request import GraspPlan, PlanRequest
from softsig_service.planning.strategies import axis_angle_between_lines, relative_poses, strategy_s_poses
from softsig_service.planning.strategy_r import c_relative_theta, solve_strategy_r
from softsig_service.planning.wrist_pose import solve_wrist_pose_unchecked

START_HEIGHT = 0.5
"""[m] the descent starts this far above the object's centre along the approach."""
APPROACH_WAYPOINTS = 4
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
    distance: float = math.inf
    approach_clear: bool = False
    """The descent showed the hand clear of table and object all along the approach (see ``Planner._place``)."""


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
            world = CollisionWorld(self.ur5, model.shapes, table_height=table_height)
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
            for T in relative_poses(center, obj.o1, hand_point, choice.theta, choice.u, choice.v):
                candidates.append(_Candidate(T=T, status=f"r:{choice.status}", iterations=choice.iterations))
        else:
            for T in strategy_s_poses(center, obj.o1, hand_point):
                candidates.append(_Candidate(T=T, status="closed_form", iterations=0))
        t_strategy = time.perf_counter() - t0

        t_ik = t_col = 0.0
        world = self._world(model, obj.table_height)
        world.set_object_unchecked(obj.primitive(), obj.primitive_pose)
        clearance = HandClearance(model.shapes, obj, obj.table_height, self._hand(model), world.placed_object)
        for c in candidates:
            if c.reasons:
                continue
            t1 = time.perf_counter()
            self._place(c, clearance, req, center)
            t2 = time.perf_counter()
            t_col += t2 - t1
            if not c.reasons:
                self._solve_grasp(c, q_now)
            t_ik += time.perf_counter() - t2
        # the branch closest to the current configuration first; the other only if the first fails
        for c in sorted((c for c in candidates if not c.reasons), key=lambda c: c.distance):
            dt_ik, dt_col = self._finish(c, req, world)
            t_ik, t_col = t_ik + dt_ik, t_col + dt_col
            if not c.reasons:
                break

        feasible = [c for c in candidates if not c.reasons and c.q_pre is not None]
        best = min(feasible, key=lambda c: c.distance) if feasible else _most_advanced(candidates)
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
            grasp_pose=best.T,
            pre_grasp_pose=best.T_pre,
            approach={
                "direction": approach_dir.tolist(),
                "frame_id": "base_link",
                "desired_distance": req.approach_distance,
                "min_distance": 0.5 * req.approach_distance,
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
            solver={
                "status": best.status,
                "iterations": best.iterations,
                "cs_method": req.cs_method,
                "cs_criterion": req.cs_criterion,
                "placement": req.placement,
            },
        )

    def _finish(self, c: _Candidate, req: PlanRequest, world: CollisionWorld) -> tuple[float, float]:
        """Pre-grasp IK, approach waypoints and collision checks of a candidate with a grasp IK solution.

        Returns (IK time, collision time) [s].
        """
        t0 = time.perf_counter()
        path = self._approach_path(c, req)
        t1 = time.perf_counter()
        if path is not None:
            self._check(c, world, path)
            if not c.reasons and req.obstacles:
                self._check_obstacles(c, req, path)
        return t1 - t0, time.perf_counter() - t1

    def _check_obstacles(self, c: _Candidate, req: PlanRequest, path: list[NDArray[np.float64]]) -> None:
        """Every arm link and hand shape against each obstacle, along the whole approach and at the grasp, with
        the plan's margin [m]: the hand may touch its target, never an obstacle."""
        model = planning_model(req.hand, req.cs_method, self.settings, req.cs_criterion, req.hand_revision)
        world = self._world(model, req.obj.table_height, "obstacle_worlds")
        Q = np.array(path)
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
        c = _Candidate(T=np.asarray(T_grasp, dtype=float), status="given", iterations=0)
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
        ik = self.ur5.solve_ik_unchecked(c.T, q_now)
        if not ik.success:
            c.reasons.append("unreachable")
            return
        c.q = ik.q
        c.ik_residual = ik.position_residual
        dq = ik.q - q_now
        c.distance = math.sqrt(float(dq @ dq))

    def _approach_path(self, c: _Candidate, req: PlanRequest) -> list[NDArray[np.float64]] | None:
        """Joint configurations from the pre-grasp down the straight approach to the grasp (None: unreachable)."""
        assert c.q is not None and c.T_pre is not None
        pre = self.ur5.solve_ik_unchecked(c.T_pre, c.q)
        if not pre.success:
            c.reasons.append("unreachable:pre_grasp")
            return None
        c.q_pre = pre.q
        c.ik_residual = max(c.ik_residual or 0.0, pre.position_residual)
        path = [pre.q]
        q = pre.q
        for k in range(1, APPROACH_WAYPOINTS):
            s = k / APPROACH_WAYPOINTS
            T = c.T_pre.copy()
            T[:3, 3] = (1 - s) * c.T_pre[:3, 3] + s * c.T[:3, 3]
            ik = self.ur5.solve_ik_unchecked(T, q, seeds=0)  # the closed-form branch nearest q, else numeric
            if not ik.success:
                c.reasons.append("unreachable:approach")
                return None
            q = ik.q
            path.append(q)
        path.append(c.q)
        if float(np.max(np.abs(np.diff(np.array(path), axis=0)))) > 0.5:
            c.reasons.append("unreachable:approach")  # a branch flip: the arm would not move straight
            return None
        return path

    def _check(self, c: _Candidate, world: CollisionWorld, path: list[NDArray[np.float64]]) -> None:
        report = world.check_waypoints(
            np.array(path), distances=False, ignore_hand_object=c.approach_clear, ignore_hand_table=c.approach_clear
        )
        if report.in_collision:
            c.reasons.extend(report.reasons)


def _most_advanced(candidates: list[_Candidate]) -> _Candidate:
    """The failed candidate that got furthest (for its reasons and poses)."""
    order = {"alignment_impossible": 0, "unreachable": 1, "unreachable:pre_grasp": 2, "unreachable:approach": 3}
    return max(candidates, key=lambda c: min((order.get(r, 4) for r in c.reasons), default=5))
