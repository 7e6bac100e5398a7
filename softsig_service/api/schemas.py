"""Request and response bodies of the REST API (pydantic; the boundary only, no behaviour).

Request bodies are strict: unknown fields, NaN and infinities are rejected (``extra="forbid"``,
``allow_inf_nan=False``), and so are strings or booleans for numbers, numbers for booleans and numbers with a
fractional part for integers (``strict=True`` on every number and flag; ``2.0`` is the integer 2, as JSON Schema
has it), with a 422 problem naming the field. Response bodies allow
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

from softsig_service.experiments.outcomes import CellSelector
from softsig_service.objects.schema import (
    MAX_OBSTACLES,
    Integer,
    ObjectSpec,
    SceneFields,
    Strict,
)
from softsig_service.signatures.capture import MIN_CAPTURE_STEP

HAND_NAME_PATTERN = r"^[a-z][a-z0-9_\-]{0,63}$"
"""Names of hands (the hand manifest's ``name`` rule)."""

HandName = Annotated[str, Field(pattern=HAND_NAME_PATTERN, description="a registered hand's name")]
JointAngle = Annotated[float, Field(ge=-7.0, le=7.0, strict=True, description="[rad]")]


class Out(BaseModel):
    """Base of response bodies: closed, every key declared (an undeclared key is a bug of the service: the
    response fails its own model, and ``tests/api/test_api_contract.py`` finds it). A free-form part of an answer
    (a hand's ``info``, a signature's JSON, a job's ``result``) is declared as an object of its own."""

    model_config = ConfigDict(extra="forbid")


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
    n_theta: Integer = Field(12, ge=2, le=72, strict=True, description="relative yaws over a half turn")
    half_width: float = Field(0.03, gt=0.0, le=0.1, strict=True, description="largest offset [m]")
    step: float = Field(
        0.01, ge=MIN_CAPTURE_STEP, le=0.1, strict=True, description="offset step [m], at most half_width"
    )
    holdout: Integer = Field(60, ge=0, le=10_000, strict=True, description="held-out simulations at random poses")
    seed: Integer = Field(0, ge=0, le=2**32 - 1, strict=True, description="seed of the held-out poses")


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
# jobs: validations and experiments
# ----------------------------------------------------------------------------------------------------------


class ValidationIn(SceneFields):
    """Validate a plan in MuJoCo (docs/design.md §7): plan the grasp of ``object`` with ``strategy``, then run
    ``trials`` rollouts with the simulated object perturbed by yaw ~ N(0, sigma_r^2) [rad] and x, y ~ N(0, sigma_t^2)
    [m]."""

    hand: HandName = "pisa_iit_softhand"
    object: ObjectSpec
    strategy: Literal["S", "C"]
    obstacles: list[ObjectSpec] = Field(
        default_factory=list, max_length=MAX_OBSTACLES,
        description="other objects on the table: planned around, simulated as free bodies that can be pushed",
    )  # fmt: skip
    sigma_r: float = Field(0.0, ge=0.0, le=3.2, strict=True, description="[rad]")
    sigma_t: float = Field(0.0, ge=0.0, le=0.5, strict=True, description="[m]")
    trials: Integer = Field(1, ge=1, le=100_000, strict=True)
    seed: Integer = Field(0, ge=0, le=2**32 - 1, strict=True)
    time_limit: float | None = Field(
        None, gt=0.0, strict=True, description="wall-time cap [s] (at most the service's cap)"
    )
    keyframes: bool = Field(
        False, strict=True,
        description="also render a keyframe strip per trial (the scene at the end of each phase, contact forces "
        "drawn as arrows; about 0.5 s more per trial): files keyframes/trial_NNN.png, linked from the result's "
        "keyframes",
    )  # fmt: skip


class ExperimentIn(Strict):
    """Run the reference experiment (docs/design.md §7, the paper's Table I): conditions x objects x strategies x
    ``trials`` per cell."""

    name: Literal["table1"] = "table1"
    hand: HandName = "pisa_iit_softhand"
    trials: Integer = Field(20, ge=1, le=100_000, strict=True, description="trials per cell")
    seed: Integer = Field(0, ge=0, le=2**32 - 1, strict=True)
    workers: Integer | None = Field(
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


class CalibrationIn(Strict):
    """Calibrate a hand to its stored real outcomes (docs/calibration.md): the manifest's declared parameters
    fitted on the cells not held out, the held-out cells predicted by the calibrated and the uncalibrated model."""

    hand: HandName
    outcomes_version: Integer | None = Field(
        None, ge=1, le=2**31 - 1, strict=True, description="the hand's outcomes version (default: the newest)"
    )
    held_out: list[CellSelector] = Field(
        default_factory=list, max_length=100, description="cells held out of the fit (any selector matching)"
    )
    parameters: list[str] = Field(
        default_factory=list, max_length=20, description="declared parameters to fit (default: all)"
    )
    ranges: dict[str, tuple[float, float]] = Field(
        default_factory=dict, description="narrower [low, high] per parameter, within the declared range"
    )
    budget: Integer = Field(2000, ge=1, le=10_000_000, strict=True, description="simulations for the fit")
    trials_per_cell: Integer = Field(20, ge=1, le=10_000, strict=True, description="draws per noisy fitted cell")
    test_trials: Integer = Field(40, ge=1, le=10_000, strict=True, description="draws per noisy held-out cell")
    seed: Integer = Field(0, ge=0, le=2**32 - 1, strict=True)
    name: str | None = Field(
        None, pattern=HAND_NAME_PATTERN, description="the calibrated variant's hand name (default: generated)"
    )
    workers: Integer | None = Field(None, ge=1, le=64, strict=True, description="simulation processes")
    time_limit: float | None = Field(
        None, gt=0.0, strict=True, description="wall-time cap [s] (at most the service's cap)"
    )
