"""Request and response bodies of the plan routes (``/v1/plans``): the request, the plan and the list of stored plans.

Same conventions as :mod:`softsig_service.api.schemas` (strict requests, open responses, SI units, world frame the
UR5 ``base_link``).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import Field

from softsig_service.api.schemas import ClosureCriterion, CsMethod, HandName, JointAngle, Out, PoseOut, Vector3
from softsig_service.objects.schema import FRAME_PATTERN, MAX_OBSTACLES, WORLD_FRAME, Integer, ObjectSpec, SceneFields
from softsig_service.planning.request import MAX_CANDIDATES, MAX_CONE
from softsig_service.planning.wrist_nlp import DEFAULT_CONE


class PlanIn(SceneFields):
    """A top-grasp request (docs/design.md §6): hand, object on the table, strategy S (bounding box), C (closure
    signature) or R (robust to the stated pose uncertainty ``sigma_r``, ``sigma_t``, with the hand's capture
    model on this object: ``capture_version``, or the newest capture signature of the hand for an object of the
    same shape, size, mass and friction), the UR5's current joints ``current_q`` [rad] (default: home). The object
    may be a point cloud in a camera's frame (``frame_id``, with that frame's pose in ``frames``); the table top is
    at ``table.height``."""

    hand: HandName
    object: ObjectSpec
    strategy: Literal["S", "C", "R"]
    obstacles: list[ObjectSpec] = Field(
        default_factory=list, max_length=MAX_OBSTACLES,
        description="other objects on the table (same table and frames): no arm link or hand shape comes within "
        "margin of one (reason collision:obstacle[i])",
    )  # fmt: skip
    sigma_r: float = Field(0.0, ge=0.0, le=1.0, strict=True, description="std. dev. of the object's yaw [rad] (R)")
    sigma_t: float = Field(0.0, ge=0.0, le=1.0, strict=True, description="std. dev. of its x and y [m] (R)")
    capture_version: Integer | None = Field(
        None, ge=1, le=2**31 - 1, strict=True,
        description="signature version of the capture model R uses (default: the newest for this object)",
    )  # fmt: skip
    current_q: tuple[JointAngle, JointAngle, JointAngle, JointAngle, JointAngle, JointAngle] | None = None
    closing_axis: Literal["minor", "major"] = Field("minor", description="object axis the CS closes across (C)")
    approach_distance: float = Field(
        0.10, ge=0.0, le=0.5, strict=True, description="pre-grasp distance along the approach [m]"
    )
    margin: float = Field(0.005, ge=0.0, le=0.05, strict=True, description="clearance kept from table and object [m]")
    cs_method: CsMethod = "ellipsoid"
    cs_criterion: ClosureCriterion = Field(
        "absolute", description="ellipsoid CS criterion: absolute [m] (docs/design.md §4) or relative half-width change"
    )
    placement: Literal["open_centre", "grasp_centre", "knuckle", "per_strategy", "previous"] = Field(
        "open_centre",
        description="hand point put over the object's centre: c_0 of the open hand or c_T of the closed hand "
        "(both strategies), knuckle (the hand's knuckle point on the palm face, declared in its manifest; both "
        "strategies: the bounding-box planner's rule), or per_strategy (S: the open points' bounding-box centre, C: "
        "the CS anchor); previous: deprecated name of per_strategy",
    )
    store: bool = Field(
        True, strict=True, description="store the plan (GET /v1/plans/{id}, image.png); false: id is null"
    )
    approach_cone: float = Field(
        DEFAULT_CONE, ge=0.0, le=MAX_CONE, strict=True,
        description="[rad] how far from straight down C may tilt the approach (its NLP over the arm's joints, for a "
        "tilted object or where no untilted pose passes; 0: straight down only)",
    )  # fmt: skip
    candidates: Integer = Field(
        1, ge=1, le=MAX_CANDIDATES, strict=True,
        description="how many distinct, fully checked grasps to return in grasps, best first (1: the strategy's)",
    )  # fmt: skip
    output_frame: str = Field(
        WORLD_FRAME, pattern=FRAME_PATTERN,
        description="frame of every returned pose and direction: base_link, base (the UR controller's: base_link "
        "turned by pi about z), object, or a frame of frames",
    )  # fmt: skip


class Duration(Out):
    """builtin_interfaces/Duration."""

    sec: int
    nanosec: int


class Stamp(Out):
    """builtin_interfaces/Time."""

    sec: int
    nanosec: int


class Header(Out):
    """std_msgs/Header (a zero stamp: the answer is not tied to a time)."""

    stamp: Stamp
    frame_id: str


class TrajectoryPoint(Out):
    """trajectory_msgs/JointTrajectoryPoint: positions [rad or the actuator's unit], velocities [per s]."""

    positions: list[float]
    velocities: list[float]
    accelerations: list[float]
    effort: list[float]
    time_from_start: Duration


class JointTrajectory(Out):
    """trajectory_msgs/JointTrajectory."""

    header: Header
    joint_names: list[str]
    points: list[TrajectoryPoint]


class Point(Out):
    """geometry_msgs/Point (or Vector3) [m]."""

    x: float
    y: float
    z: float


class Orientation(Out):
    """geometry_msgs/Quaternion."""

    x: float
    y: float
    z: float
    w: float


class PoseMsg(Out):
    """geometry_msgs/Pose."""

    position: Point
    orientation: Orientation


class PoseStamped(Out):
    """geometry_msgs/PoseStamped."""

    header: Header
    pose: PoseMsg


class Vector3Stamped(Out):
    """geometry_msgs/Vector3Stamped (a unit direction)."""

    header: Header
    vector: Point


class GripperTranslation(Out):
    """moveit_msgs/GripperTranslation: a direction and distances [m]."""

    direction: Vector3Stamped
    desired_distance: float
    min_distance: float


class MoveitGrasp(Out):
    """moveit_msgs/Grasp, field for field (docs/planning.md)."""

    id: str
    pre_grasp_posture: JointTrajectory
    grasp_posture: JointTrajectory
    grasp_pose: PoseStamped
    grasp_quality: float
    pre_grasp_approach: GripperTranslation
    post_grasp_retreat: GripperTranslation
    post_place_retreat: GripperTranslation
    max_contact_force: float
    allowed_touch_objects: list[str]


class RankedGrasp(Out):
    """One of a plan's grasps, best first: every one passed the IK, approach, lift and collision checks."""

    rank: int = Field(description="1 for the best")
    id: str = Field(description="hand/strategy/object/rank, as moveit_grasp.id")
    label: str = Field(description="which candidate: the strategy's own yaw branch, or theta, shift and branch")
    primary: bool = Field(description="the strategy's own pose (else an alternative)")
    grasp_quality: float = Field(ge=0.0, le=1.0, description="estimated probability of carrying the object")
    quality_model: Literal["capture", "geometric"] = Field(
        description="capture: the hand's capture model of the object; geometric: the stated geometric model"
    )
    grasp_pose: PoseOut = Field(description="the flange (tool0) at the grasp")
    pre_grasp_pose: PoseOut = Field(description="the flange (tool0) at the pre-grasp")
    grasp_frame_pose: PoseOut = Field(description="the hand's grasp frame at the grasp (the flange's unless the hand "
                                      "states a grasp_frame)")  # fmt: skip
    joint_positions: list[float] = Field(description="UR5 joints at the grasp [rad]")
    pre_grasp_joint_positions: list[float] = Field(description="UR5 joints at the pre-grasp [rad]")
    clearance: float | None = Field(None, description="[m] from the open hand to table and object at the grasp")
    ik_residual: float | None = Field(None, description="[m] largest IK position residual")
    approach_trajectory: JointTrajectory = Field(description="pre-grasp to grasp, as the validation executes it")
    retreat_trajectory: JointTrajectory = Field(description="the lift after the grasp, as the validation executes")
    moveit_grasp: MoveitGrasp


class Approach(Out):
    """Straight approach: unit ``direction`` in ``frame_id``, distances [m] (moveit_msgs/GripperTranslation)."""

    direction: Vector3
    frame_id: str = "base_link"
    desired_distance: float
    min_distance: float
    retreat_distance: float = Field(description="[m] the lift after the grasp, straight up (post_grasp_retreat)")


class Quality(Out):
    """Quality terms: ``alignment_error`` [rad], ``ik_residual`` [m], ``clearance`` [m]; ``expected_capture``
    (strategy R only): the capture probability R expects under the stated pose noise, in [0, 1]."""

    alignment_error: float | None = None
    ik_residual: float | None = None
    clearance: float | None = None
    expected_capture: float | None = None


class Timing(Out):
    """Wall time of the planner [s], by part."""

    strategy: float = Field(description="the strategy's pose search (S, C: alignment; R: the robust search)")
    ik: float = Field(description="inverse kinematics of the grasp and pre-grasp")
    collision: float = Field(description="collision checks along the approach")
    total: float = Field(description="the whole plan")


class ClosureCommand(Out):
    """The hand's closure (moveit_msgs/Grasp's grasp posture): actuator controls ramped from ``open`` to
    ``closed`` over ``duration`` [s] (units of each actuator: [rad], [m] or a synergy's [0, 1])."""

    actuators: list[str]
    commands: list[str] = Field(
        default_factory=list,
        description="what a robot stack commands for each actuator: the joint a posture closure servos, else the "
        "actuator (the names of moveit_grasp's postures)",
    )
    open: list[float]
    closed: list[float]
    duration: float


class Solver(Out):
    """How the plan was found: the strategy's ``status`` and ``iterations``, and the options it ran with."""

    status: str
    iterations: int | None = None
    cs_method: CsMethod
    cs_criterion: ClosureCriterion
    placement: Literal["open_centre", "grasp_centre", "knuckle", "per_strategy"]


class PlanOut(Out):
    """A grasp plan; maps one to one onto moveit_msgs/Grasp (docs/planning.md). ``grasp_pose`` and
    ``pre_grasp_pose`` are poses of the flange ``tool0`` in ``base_link``; joints [rad]; timing [s]."""

    id: str | None = Field(None, description="the stored plan's id; null when the plan was not stored")
    created_at: datetime | None = Field(None, description="when the plan was stored (UTC); null when not stored")
    success: bool = Field(description="whether a pose passed the IK, approach and collision checks")
    reasons: list[str] = Field(
        description="why the plan failed, empty on success: alignment_impossible, unreachable, "
        "unreachable:pre_grasp, unreachable:approach, collision:table, collision:object, collision:self"
    )
    strategy: str = Field(description="S (bounding box), C (closure signature) or R (capture model)")
    hand: str = Field(description="the hand's name")
    object: dict[str, Any] = Field(description="the object as planned, on its nominal pose")
    joint_names: list[str] = Field(description="the UR5's joints, in the order of the joint positions")
    joint_positions: list[float] | None = Field(None, description="UR5 joints at the grasp [rad]")
    pre_grasp_joint_positions: list[float] | None = Field(None, description="UR5 joints at the pre-grasp [rad]")
    grasp_pose: PoseOut | None = Field(None, description="the flange (tool0) at the grasp")
    pre_grasp_pose: PoseOut | None = Field(None, description="the flange (tool0) at the pre-grasp")
    grasp_frame_pose: PoseOut | None = Field(
        None, description="the hand's grasp frame at the grasp (the flange's unless the hand states a grasp_frame)"
    )
    approach: Approach
    quality: Quality
    timing: Timing
    closure: ClosureCommand
    solver: Solver
    output_frame: str = Field(WORLD_FRAME, description="the frame of every pose and direction of the plan")
    output_frame_pose: PoseOut | None = Field(None, description="the pose of output_frame in base_link")
    grasps: list[RankedGrasp] = Field(
        default_factory=list, description="the feasible grasps, best first (the plan's own first)"
    )
    links: dict[str, str] = Field(default_factory=dict, description="URLs of the stored plan and its image")
    hand_revision: int = Field(description="the registry's revision of the hand the plan was made with")


class PlanSummary(Out):
    """A stored plan, briefly."""

    id: str
    hand: str
    strategy: str
    success: bool
    created_at: datetime
    links: dict[str, str] = Field(default_factory=dict)


class PlanList(Out):
    """Stored plans, newest first."""

    items: list[PlanSummary]
    total: int
    limit: int
    offset: int
