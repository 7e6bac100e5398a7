"""Request and response bodies of the REST API (pydantic; the boundary only, no behaviour).

Request bodies are strict: unknown fields, NaN and infinities are rejected (``extra="forbid"``,
``allow_inf_nan=False``), and so are strings or booleans for numbers, numbers for booleans and floats for
integers (``strict=True`` on every number and flag), with a 422 problem naming the field. Response bodies allow
extra keys, so that a field added to a result type reaches clients without a schema change.

Units and frames (docs/design.md §3): SI units (m, rad, s, kg, N); the world frame is the UR5 ``base_link`` (z
up); poses are ``{"frame_id", "position": {x, y, z}, "orientation": {x, y, z, w}}`` (geometry_msgs order); signatures
are in the hand frame (origin at the flange, +z the approach, +x across the palm).

This module imports nothing heavy (no MuJoCo, no NumPy at import), so the client can use it.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from softsig_service.objects.schema import (
    ObjectSpec,
    Strict,
)

HAND_NAME_PATTERN = r"^[a-z][a-z0-9_\-]{0,63}$"
"""Names of hands (the hand manifest's ``name`` rule)."""

HandName = Annotated[str, Field(pattern=HAND_NAME_PATTERN, description="a registered hand's name")]
JointAngle = Annotated[float, Field(ge=-7.0, le=7.0, strict=True, description="[rad]")]


class Out(BaseModel):
    """Base of response bodies: extra keys pass through."""

    model_config = ConfigDict(extra="allow")


# ----------------------------------------------------------------------------------------------------------
# common wire types
# ----------------------------------------------------------------------------------------------------------


class Vector3(Out):
    """A 3-D vector: a position [m], a direction (unit) or a force [N], by context; every vector of the API has
    this form."""

    x: float
    y: float
    z: float


class Quaternion(Out):
    """A unit quaternion, named fields (geometry_msgs order)."""

    x: float
    y: float
    z: float
    w: float


class PoseOut(Out):
    """A pose of the UR5 flange ``tool0`` (= the hand frame) in ``frame_id``."""

    frame_id: str
    position: Vector3
    orientation: Quaternion


class Problem(Out):
    """RFC 9457 problem details (``application/problem+json``), with the offending ``field`` named."""

    type: str = Field(description="URI of the problem type (urn:softsig:problem:<slug>)")
    title: str
    status: int
    detail: str | None = None
    instance: str | None = Field(None, description="the request path")
    field: str | None = Field(None, description="dotted path of the offending field (e.g. object.size[2])")
    value: Any = Field(None, description="the offending value (shortened)")
    choices: list[str] | None = Field(None, description="the valid values, where they are a closed set")
    errors: list[dict[str, Any]] | None = Field(None, description="every validation error: field, message, type")
    request_id: str | None = None


# ----------------------------------------------------------------------------------------------------------
# hands
# ----------------------------------------------------------------------------------------------------------


class HandFile(Out):
    """A file of an uploaded hand: path relative to its folder, size [bytes], SHA-256."""

    path: str
    size: int
    sha256: str


class HandSummary(Out):
    """A registered hand."""

    name: str
    builtin: bool
    revision: int
    etag: str
    kind: str | None = None
    description: str = ""
    model_format: str | None = None
    reference_points: list[str] = Field(default_factory=list)
    signature_count: int = 0
    created_at: datetime
    updated_at: datetime
    links: dict[str, str] = Field(default_factory=dict)


class HandOut(HandSummary):
    """A registered hand with its model summary (``info``: joints, actuators, mass [kg], reference points...)."""

    info: dict[str, Any]
    files: list[HandFile] = Field(default_factory=list)


class HandList(Out):
    """Registered hands, by name."""

    items: list[HandSummary]
    total: int
    limit: int
    offset: int


# ----------------------------------------------------------------------------------------------------------
# signatures
# ----------------------------------------------------------------------------------------------------------


ClosureCriterion = Literal["absolute", "relative"]
"""The ellipsoid method's criterion (``softsig_service.signatures.closure.CRITERIA``; kept literal here so that
this module imports nothing heavy)."""
CRITERION_DESCRIPTION = (
    "ellipsoid method only: 'absolute' (default) elects the axis whose half-width changes most in metres, "
    "delta_k = a_k(T) - a_k(0) [m]; 'relative' the one whose half-width changes most relative to its initial "
    "length, delta_k / a_k(0). Ignored (and not stored) for pca and mesh."
)


CsMethod = Literal["ellipsoid", "pca", "mesh"]
"""The closure-signature method (``softsig_service.signatures.closure.METHODS``), named ``cs_method`` everywhere."""


class ClosureSignatureIn(Strict):
    """Compute the closure signature from a simulated free closure of the hand (docs/design.md §4)."""

    cs_method: CsMethod = "ellipsoid"
    cs_criterion: ClosureCriterion = Field("absolute", description=CRITERION_DESCRIPTION)


class StiffnessSignatureIn(Strict):
    """Compute the stiffness signature: grasp ``object`` in MuJoCo, 6x6 stiffness and break forces
    (docs/design.md §5)."""

    object: ObjectSpec


class CaptureSignatureIn(Strict):
    """Compute the capture model of strategy R: grasp ``object`` in MuJoCo at ``n_theta`` relative yaws x offsets
    ``-half_width .. half_width`` [m] in steps of ``step`` [m] along both hand axes, plus ``holdout`` random
    checks of the model (docs/planning.md, strategy R)."""

    object: ObjectSpec
    n_theta: int = Field(12, ge=2, le=72, strict=True, description="relative yaws over a half turn")
    half_width: float = Field(0.03, gt=0.0, le=0.1, strict=True, description="largest offset [m]")
    step: float = Field(0.01, gt=0.0, le=0.1, strict=True, description="offset step [m], at most half_width")
    holdout: int = Field(60, ge=0, le=10_000, strict=True, description="held-out simulations at random poses")
    seed: int = Field(0, ge=0, le=2**32 - 1, strict=True, description="seed of the held-out poses")


class SignatureSummary(Out):
    """One stored signature version. Closure signatures: ``cs_method`` and ``cs_criterion`` (the ellipsoid
    method's criterion, "absolute": deltas in metres, "relative": dimensionless; null for pca and mesh).
    Stiffness signatures and capture models: ``object``, the name of the object grasped (``cs_method`` and
    ``cs_criterion`` null)."""

    hand: str
    version: int
    kind: Literal["closure", "stiffness", "capture"] | str
    cs_method: CsMethod | None = None
    cs_criterion: ClosureCriterion | None = None
    object: str | None = None
    source: Literal["simulation", "markers"] | str
    hand_revision: int
    etag: str
    created_at: datetime
    links: dict[str, str] = Field(default_factory=dict)


class SignatureOut(SignatureSummary):
    """A stored signature version with its parameters and the signature JSON (as ``softsig signature ... --json``)."""

    params: dict[str, Any]
    signature: dict[str, Any]


class SignatureList(Out):
    """Signature versions, newest first."""

    items: list[SignatureSummary]
    total: int
    limit: int
    offset: int


# ----------------------------------------------------------------------------------------------------------
# plans
# ----------------------------------------------------------------------------------------------------------


class PlanIn(Strict):
    """A top-grasp request (docs/design.md §6): hand, object on the table, strategy S (bounding box), C (closure
    signature) or R (robust to the stated pose uncertainty ``sigma_r``, ``sigma_t``, with the hand's capture
    model on this object: ``capture_version``, or the newest capture signature of the hand for an object of the
    same shape, size, mass and friction), the UR5's current joints ``current_q`` [rad] (default: home)."""

    hand: HandName
    object: ObjectSpec
    strategy: Literal["S", "C", "R"]
    sigma_r: float = Field(0.0, ge=0.0, le=1.0, strict=True, description="std. dev. of the object's yaw [rad] (R)")
    sigma_t: float = Field(0.0, ge=0.0, le=1.0, strict=True, description="std. dev. of its x and y [m] (R)")
    capture_version: int | None = Field(
        None, ge=1, strict=True, description="signature version of the capture model R uses (default: the newest "
        "for this object)",
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
    placement: Literal["open_centre", "grasp_centre", "previous"] = Field(
        "open_centre",
        description="hand point put over the object's centre: c_0 of the open hand or c_T of the closed hand "
        "(both strategies), or the previous per-strategy rule",
    )
    store: bool = Field(
        True, strict=True, description="store the plan (GET /v1/plans/{id}, image.png); false: id is null"
    )


class Approach(Out):
    """Straight approach: unit ``direction`` in ``frame_id``, distances [m] (moveit_msgs/GripperTranslation)."""

    direction: Vector3
    frame_id: str = "base_link"
    desired_distance: float
    min_distance: float


class Quality(Out):
    """Quality terms: ``alignment_error`` [rad], ``ik_residual`` [m], ``clearance`` [m]; ``expected_capture``
    (strategy R only): the capture probability R expects under the stated pose noise, in [0, 1]."""

    alignment_error: float | None = None
    ik_residual: float | None = None
    clearance: float | None = None
    expected_capture: float | None = None


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
    grasp_pose: PoseOut | None = None
    pre_grasp_pose: PoseOut | None = None
    approach: Approach
    quality: Quality
    timing: dict[str, float] = Field(description="wall time [s] by part: strategy, ik, collision, total")
    closure: dict[str, Any] = Field(default_factory=dict, description="the hand's closure command (grasp posture)")
    solver: dict[str, Any] = Field(
        default_factory=dict, description="status and iterations of the strategy, CS method, criterion, placement"
    )
    links: dict[str, str] = Field(default_factory=dict, description="URLs of the stored plan and its image")


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


# ----------------------------------------------------------------------------------------------------------
# jobs: validations and experiments
# ----------------------------------------------------------------------------------------------------------


class ValidationIn(Strict):
    """Validate a plan in MuJoCo (docs/design.md §7): plan the grasp of ``object`` with ``strategy``, then run
    ``trials`` rollouts with the simulated object perturbed by yaw ~ N(0, sigma_r^2) [rad] and x, y ~ N(0, sigma_t^2)
    [m]."""

    hand: HandName = "pisa_iit_softhand"
    object: ObjectSpec
    strategy: Literal["S", "C"]
    sigma_r: float = Field(0.0, ge=0.0, le=3.2, strict=True, description="[rad]")
    sigma_t: float = Field(0.0, ge=0.0, le=0.5, strict=True, description="[m]")
    trials: int = Field(1, ge=1, le=100_000, strict=True)
    seed: int = Field(0, ge=0, le=2**32 - 1, strict=True)
    time_limit: float | None = Field(
        None, gt=0.0, strict=True, description="wall-time cap [s] (at most the service's cap)"
    )


class ExperimentIn(Strict):
    """Run the reference experiment (docs/design.md §7, the paper's Table I): conditions x objects x strategies x
    ``trials`` per cell."""

    name: Literal["table1"] = "table1"
    hand: HandName = "pisa_iit_softhand"
    trials: int = Field(20, ge=1, le=100_000, strict=True, description="trials per cell")
    seed: int = Field(0, ge=0, le=2**32 - 1, strict=True)
    workers: int | None = Field(
        None, ge=1, le=64, strict=True, description="worker processes (default: the job's own choice)"
    )
    time_limit: float | None = Field(
        None, gt=0.0, strict=True, description="wall-time cap [s] (at most the service's cap)"
    )


class JobOut(Out):
    """A job: ``status`` queued | running | succeeded | failed | cancelled | timed_out, ``progress`` in [0, 1]."""

    id: str
    kind: str
    status: str
    progress: float
    message: str = ""
    params: dict[str, Any]
    result: dict[str, Any] | None = None
    error: dict[str, Any] | None = None
    time_limit: float = Field(description="wall-time cap [s]")
    cancel_requested: bool = False
    attempts: int = Field(
        0, description="how many times a service process has started the job (more than 1: its process died or "
        "the service stopped, and another process resumed it)",
    )  # fmt: skip
    created_at: datetime
    started_at: datetime | None = None
    finished_at: datetime | None = None
    links: dict[str, str] = Field(default_factory=dict)


class JobList(Out):
    """Jobs, newest first."""

    items: list[JobOut]
    total: int
    limit: int
    offset: int


class JobFile(Out):
    """A result file of a job: name, size [bytes], media type and download URL."""

    name: str
    size: int
    media_type: str
    url: str


class JobFiles(Out):
    """The result files of a job, by name."""

    items: list[JobFile]
    total: int
    limit: int
    offset: int


# ----------------------------------------------------------------------------------------------------------
# operations
# ----------------------------------------------------------------------------------------------------------


class Health(Out):
    """Liveness."""

    status: Literal["ok"]


class Readiness(Out):
    """Readiness: every check ``ok`` or the reason it is not."""

    status: Literal["ready", "not_ready"]
    checks: dict[str, str]
