"""What a plan is asked and what it answers: :class:`PlanRequest` (validated once, here) and :class:`GraspPlan`
(whose JSON maps one to one onto moveit_msgs/Grasp, see docs/planning.md).

Frames: world = UR5 ``base_link`` (z up); poses are of the flange ``tool0`` (= the hand frame); lengths in [m],
angles in [rad].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from softsig_service.arm.ur5 import HOME_Q
from softsig_service.errors import InvalidInput
from softsig_service.geometry.checks import as_finite_array
from softsig_service.geometry.quaternions import rotation_to_quat
from softsig_service.geometry.transforms import pose_wire
from softsig_service.objects import TableObject
from softsig_service.objects.schema import MAX_OBSTACLES, WORLD_FRAME
from softsig_service.planning.hand_model import DEFAULT_PLACEMENT, DEPRECATED_PLACEMENTS, PLACEMENTS, Placement
from softsig_service.planning.strategies import STRATEGIES
from softsig_service.planning.wrist_nlp import DEFAULT_CONE
from softsig_service.signatures.capture import CaptureModel
from softsig_service.signatures.closure_types import CRITERIA, Criterion

MAX_CONE = math.radians(60.0)
"""[rad] the widest approach cone a request may ask for."""
MAX_CANDIDATES = 12
"""Most grasps a plan returns (the alternatives of :mod:`softsig_service.planning.ranking` number 12 at most)."""


@dataclass(frozen=True)
class PlanRequest:
    """A top-grasp request. ``current_q`` [rad] defaults to the UR5's ``HOME_Q``; distances in [m].

    Validated here, once (the boundary): the planner's internal steps do not check their inputs again.
    """

    hand: str
    obj: TableObject
    strategy: Literal["S", "C", "R"]
    current_q: tuple[float, ...] | None = None
    closing_axis: Literal["minor", "major"] = "minor"
    approach_distance: float = 0.10
    margin: float = 0.005
    cs_method: Literal["ellipsoid", "pca", "mesh"] = "ellipsoid"
    cs_criterion: Criterion = "absolute"
    placement: Placement = DEFAULT_PLACEMENT
    sigma_r: float = 0.0
    """[rad] standard deviation of the object's yaw about its nominal pose (strategy R plans for it)."""
    sigma_t: float = 0.0
    """[m] standard deviation of the object's x and y about its nominal pose (strategy R plans for it)."""
    capture: CaptureModel | None = None
    """The hand's capture model on this object (strategy R; :mod:`softsig_service.signatures.capture`)."""
    hand_revision: str = ""
    """What names the content of ``hand`` (the registry's ETag of the hand; "" for a folder as it is on disk): the
    planner's cached models of the hand are keyed by it, so a replaced hand is never planned with its old model."""
    relative_pose: tuple[float, float, float] | None = None
    """Put the hand at this relative pose (theta [rad], u, v [m]; :mod:`softsig_service.signatures.capture`)
    instead of the strategy's choice (diagnostics and the capture model's simulations)."""
    approach_cone: float = DEFAULT_CONE
    """[rad] how far from straight down strategy C's NLP over the arm's joints may tilt the approach, when no
    closed-form pose passes (:mod:`softsig_service.planning.wrist_nlp`; 0: straight down only)."""
    candidates: int = 1
    """How many distinct, fully checked grasps to return, best first (``grasps``; at most :data:`MAX_CANDIDATES`):
    1 is the strategy's grasp alone; more adds the alternatives of :mod:`softsig_service.planning.ranking`."""
    obstacles: tuple[TableObject, ...] = ()
    """Other objects on the table (in ``base_link``, on the same table): no arm link or hand shape may come within
    ``margin`` of one anywhere on the approach or at the grasp (reason ``collision:obstacle[i]``, ``i`` its index)."""

    def __post_init__(self) -> None:
        if self.strategy not in STRATEGIES:
            raise InvalidInput("unknown strategy", field="strategy", value=self.strategy, choices=STRATEGIES)
        for name, value in (("sigma_r", self.sigma_r), ("sigma_t", self.sigma_t)):
            if not (math.isfinite(value) and 0.0 <= value <= 1.0):
                raise InvalidInput("must be a finite number in [0, 1]", field=name, value=value)
        if (
            isinstance(self.candidates, bool)
            or not isinstance(self.candidates, int)
            or not (1 <= self.candidates <= MAX_CANDIDATES)
        ):
            raise InvalidInput(f"must be an integer in [1, {MAX_CANDIDATES}]", field="candidates",
                               value=self.candidates)  # fmt: skip
        if self.strategy == "R" and self.capture is None and self.relative_pose is None:
            raise InvalidInput("strategy R needs the hand's capture model on this object", field="capture")
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        if len(self.obstacles) > MAX_OBSTACLES:
            raise InvalidInput(f"at most {MAX_OBSTACLES} obstacles", field="obstacles", value=len(self.obstacles))
        for i, obstacle in enumerate(self.obstacles):
            if not isinstance(obstacle, TableObject):
                raise InvalidInput("expected an object", field=f"obstacles[{i}]", value=repr(obstacle))
        if self.relative_pose is not None:
            rel = as_finite_array(self.relative_pose, (3,), "relative_pose")
            object.__setattr__(self, "relative_pose", tuple(float(x) for x in rel))
        if self.placement not in PLACEMENTS:
            raise InvalidInput("unknown placement", field="placement", value=self.placement, choices=PLACEMENTS)
        object.__setattr__(self, "placement", DEPRECATED_PLACEMENTS.get(self.placement, self.placement))
        if self.cs_criterion not in CRITERIA:
            raise InvalidInput("unknown criterion", field="cs_criterion", value=self.cs_criterion, choices=CRITERIA)
        if self.current_q is not None:
            q = as_finite_array(self.current_q, (len(HOME_Q),), "current_q")
            object.__setattr__(self, "current_q", tuple(float(v) for v in q))
        if self.closing_axis not in ("minor", "major"):
            raise InvalidInput("unknown closing axis", field="closing_axis", value=self.closing_axis,
                               choices=("minor", "major"))  # fmt: skip
        for name, value, lo, hi, unit in (("approach_distance", self.approach_distance, 0.0, 0.5, "m"),
                                          ("margin", self.margin, 0.0, 0.05, "m"),
                                          ("approach_cone", self.approach_cone, 0.0, MAX_CONE, "rad")):  # fmt: skip
            if not (math.isfinite(value) and lo <= value <= hi):
                raise InvalidInput(f"must be within [{lo:g}, {hi:g}] {unit}", field=name, value=value)


@dataclass(frozen=True)
class GraspPlan:
    """A planned top grasp; its JSON maps one to one onto moveit_msgs/Grasp (see docs/planning.md)."""

    success: bool
    reasons: list[str]
    strategy: str
    hand: str
    object: dict[str, Any]
    joint_names: list[str]
    joint_positions: list[float] | None
    pre_grasp_joint_positions: list[float] | None
    grasp_pose: NDArray[np.float64] | None
    pre_grasp_pose: NDArray[np.float64] | None
    approach: dict[str, Any]
    quality: dict[str, float | None]
    timing: dict[str, float]
    closure: dict[str, Any]
    solver: dict[str, Any] = field(default_factory=dict)
    grasps: list[dict[str, Any]] = field(default_factory=list)
    grasp_frame_pose: NDArray[np.float64] | None = None
    """The hand's grasp frame at the grasp (4x4, base_link): ``grasp_pose`` (the flange's) times the hand's
    ``T_HG``; the same pose when the hand frame is its grasp frame."""
    """The feasible grasps, best first (the first is the plan's own): rank, id, grasp_quality and its model,
    flange poses (4x4, base_link) and joint positions [rad] (:func:`~softsig_service.planning.planner.Planner.plan`)."""

    def to_json_dict(
        self, frame_id: str = WORLD_FRAME, T_base_frame: NDArray[np.float64] | None = None
    ) -> dict[str, Any]:
        """The plan JSON with every pose and direction in the frame ``frame_id`` whose pose in ``base_link`` is
        ``T_base_frame`` (4x4; default ``base_link`` itself): poses as ``{"frame_id", "position": {x,y,z},
        "orientation": {x,y,z,w}}``; each grasp also as ``moveit_grasp`` (:mod:`softsig_service.planning.moveit`)
        with its ``approach_trajectory`` and ``retreat_trajectory`` as trajectory_msgs/JointTrajectory JSON."""
        from softsig_service.planning.moveit import joint_trajectory, moveit_grasp

        T_frame = np.eye(4) if T_base_frame is None else np.asarray(T_base_frame, dtype=np.float64)
        inverse = np.linalg.inv(T_frame)

        def out(T: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.asarray(inverse @ T, dtype=np.float64)

        def pose(T: NDArray[np.float64] | None) -> dict[str, Any] | None:
            if T is None:
                return None
            To = out(T)
            return pose_wire(To[:3, 3], rotation_to_quat(To[:3, :3]), frame_id)

        def turned(v: Any) -> NDArray[np.float64]:
            return np.asarray(inverse[:3, :3] @ np.asarray(v, dtype=np.float64), dtype=np.float64)

        up = turned([0.0, 0.0, 1.0])
        approach = dict(self.approach, frame_id=frame_id)
        if "direction" in approach:
            approach["direction"] = turned(approach["direction"]).tolist()
        grasps = []
        for g in self.grasps:
            grasp_id = f"{self.hand}/{self.strategy}/{self.object.get('name') or self.object.get('kind')}/{g['rank']}"
            trajectories = {
                name: joint_trajectory(t["joint_names"], t["positions"], t["time_from_start"], t["velocities"])
                for name in ("approach_trajectory", "retreat_trajectory")
                if (t := g.get(name)) is not None
            }
            message = moveit_grasp(
                grasp_id, out(g["grasp_pose"]), frame_id, g["grasp_quality"], self.closure,
                turned(g["grasp_frame_pose"][:3, 2]), float(self.approach.get("desired_distance", 0.0)), up,
                float(self.approach.get("retreat_distance", 0.0)),
            )  # fmt: skip
            grasps.append({**g, "id": grasp_id, "grasp_pose": pose(g["grasp_pose"]),
                           "pre_grasp_pose": pose(g["pre_grasp_pose"]),
                           "grasp_frame_pose": pose(g["grasp_frame_pose"]), **trajectories,
                           "moveit_grasp": message})  # fmt: skip
        return {
            "success": self.success,
            "reasons": list(self.reasons),
            "strategy": self.strategy,
            "hand": self.hand,
            "object": self.object,
            "joint_names": list(self.joint_names),
            "joint_positions": self.joint_positions,
            "pre_grasp_joint_positions": self.pre_grasp_joint_positions,
            "grasp_pose": pose(self.grasp_pose),
            "pre_grasp_pose": pose(self.pre_grasp_pose),
            "grasp_frame_pose": pose(self.grasp_frame_pose if self.grasp_frame_pose is not None else self.grasp_pose),
            "approach": approach,
            "quality": self.quality,
            "timing": self.timing,
            "closure": self.closure,
            "solver": self.solver,
            "output_frame": frame_id,
            "output_frame_pose": pose_wire(T_frame[:3, 3], rotation_to_quat(T_frame[:3, :3]), WORLD_FRAME),
            "grasps": grasps,
        }
