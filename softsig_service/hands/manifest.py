"""The hand manifest ``hand.toml``: its schema and loader.

A manifest names the model file (MJCF, URDF or a ``.urdf.xacro`` with its ``xacro_args``, relative to the
manifest's folder), the mount body and optionally the hand frame's pose in it (``mount_pose``; without it the
mount body's frame is the hand frame, which sits at the UR5 flange ``tool0``; docs/design.md §3), optionally the
grasp frame's pose in the hand frame (``grasp_frame``: +z the approach out of the palm, +x across it; without it the
hand frame is the grasp frame), the
reference points tracked through a closure, the closure command and the simulation settings. Every bad value raises
:class:`~softsig_service.errors.InvalidManifest` naming the field (a dotted path) and, where they are a closed
set, the valid choices.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from softsig_service.errors import InvalidManifest
from softsig_service.hands.calibration import CalibrationSection

NAME_PATTERN = r"^[a-z][a-z0-9_\-]{0,63}$"
MODEL_SUFFIXES = (".xml", ".urdf", ".xacro")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class ReferencePoint(_Strict):
    """A tracked point: an MJCF ``site``, or a ``body`` plus an ``offset`` [m] in that body's frame."""

    name: str = Field(min_length=1, max_length=64)
    site: str | None = None
    body: str | None = None
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _one_anchor(self) -> ReferencePoint:
        if (self.site is None) == (self.body is None):
            raise ValueError("give exactly one of 'site' or 'body' (with an optional 'offset')")
        if self.site is not None and self.offset != (0.0, 0.0, 0.0):
            raise ValueError("'offset' applies to a 'body' reference point, not to a 'site'")
        return self


class ActuatorClosure(_Strict):
    """Closure by ramping one or more actuators' controls from ``open`` to ``closed`` over ``duration`` [s].

    ``settle`` [s] is the time held at the closed command before the last sample. Units of ``open``/``closed``
    are the actuators' control units (stated in the hand's README).
    """

    kind: Literal["actuator"]
    actuators: list[str] = Field(min_length=1)
    open: float
    closed: float
    duration: float = Field(1.0, gt=0.0, le=30.0)
    settle: float = Field(0.5, ge=0.0, le=30.0)


class PostureClosure(_Strict):
    """Closure of a fully actuated hand: joint targets interpolated from ``open`` to ``closed`` postures.

    Postures map joint names to positions [rad] (hinge) or [m] (slide). A position servo of gain ``kp``
    [N·m/rad or N/m] and damping ``kv`` is added to each named joint at load time.
    """

    kind: Literal["posture"]
    open: dict[str, float] = Field(min_length=1)
    closed: dict[str, float] = Field(min_length=1)
    duration: float = Field(1.0, gt=0.0, le=30.0)
    settle: float = Field(0.5, ge=0.0, le=30.0)
    kp: float = Field(50.0, gt=0.0)
    kv: float = Field(1.0, ge=0.0)
    force_limit: float | None = Field(None, gt=0.0, description="servo force limit [N] or [N·m]")

    @model_validator(mode="after")
    def _same_joints(self) -> PostureClosure:
        if set(self.open) != set(self.closed):
            missing = sorted(set(self.open) ^ set(self.closed))
            raise ValueError(f"open and closed postures must name the same joints; differing: {missing}")
        return self


class SynergyClosure(_Strict):
    """Closure along one synergy: a scalar ``s`` ramped from ``open`` to ``closed`` (within [0, 1]) drives every
    coupled joint as ``q_j = multiplier_j * s + offset_j`` [rad] or [m], clipped to the joint's limits.

    The coupled joints and their multipliers come from ``multipliers`` (with optional ``offsets``), or from the
    URDF ``<mimic>`` tags of ``synergy_joint``: that joint (multiplier 1, offset 0) and every joint whose chain of
    mimics ends at it (their mimic equalities are replaced by this closure). ``realisation``:

    * ``"kinematic"``: a position servo on each coupled joint (gain ``kp`` [N·m/rad or N/m], damping ``kv``,
      optional ``force_limit``) with the target ``multiplier * s + offset``: a position-controlled hand.
    * ``"adaptive"``: one fixed tendon of length ``sum_j multiplier_j q_j`` (the multipliers are its moment arms)
      pulled by a force source of ``stiffness * s`` [N·m], every coupled joint a spring of ``stiffness``
      [N·m/rad] about ``offset_j``; in free space each joint settles at ``multiplier_j * s + offset_j`` and a
      blocked joint leaves the others where they would be in free space (the Pisa/IIT SoftHand's transmission).

    ``damping`` [N·m·s/rad] and ``armature`` [kg·m²] are set on every coupled joint (approximate values that keep
    light URDF links stable at a 2 ms step).
    """

    kind: Literal["synergy"]
    realisation: Literal["kinematic", "adaptive"] = "adaptive"
    synergy_joint: str | None = Field(None, min_length=1)
    multipliers: dict[str, float] | None = Field(None, min_length=1)
    offsets: dict[str, float] = Field(default_factory=dict)
    open: float = Field(0.0, ge=0.0, le=1.0)
    closed: float = Field(1.0, ge=0.0, le=1.0)
    duration: float = Field(1.0, gt=0.0, le=30.0)
    settle: float = Field(0.5, ge=0.0, le=30.0)
    kp: float = Field(5.0, gt=0.0)
    kv: float = Field(0.05, ge=0.0)
    force_limit: float | None = Field(None, gt=0.0, description="kinematic servo force limit [N] or [N·m]")
    stiffness: float = Field(0.1, gt=0.0, description="adaptive: joint stiffness [N·m/rad], uniform")
    damping: float = Field(0.005, ge=0.0, description="joint damping [N·m·s/rad]")
    armature: float = Field(1e-4, ge=0.0, description="joint armature [kg·m²]")

    @model_validator(mode="after")
    def _one_source(self) -> SynergyClosure:
        if (self.synergy_joint is None) == (self.multipliers is None):
            raise ValueError("give exactly one of 'synergy_joint' (multipliers from its mimic tags) or 'multipliers'")
        if self.synergy_joint is not None and self.offsets:
            raise ValueError("'offsets' go with 'multipliers'; with 'synergy_joint' they come from the mimic tags")
        extra = sorted(set(self.offsets) - set(self.multipliers or {}))
        if extra:
            raise ValueError(f"offsets name joints without a multiplier: {extra}")
        if self.open == self.closed:
            raise ValueError("'open' and 'closed' must differ")
        return self


Closure = Annotated[ActuatorClosure | PostureClosure | SynergyClosure, Field(discriminator="kind")]


class MountPose(_Strict):
    """The hand frame's pose in the mount body's frame: ``xyz`` [m] and ``rpy`` [rad] (URDF roll, pitch, yaw:
    ``R = Rz(yaw) Ry(pitch) Rx(roll)``) or ``quaternion`` ``{x, y, z, w}`` (normalised on load)."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] | None = None
    quaternion: dict[str, float] | None = None

    @model_validator(mode="after")
    def _one_orientation(self) -> MountPose:
        if self.rpy is not None and self.quaternion is not None:
            raise ValueError("give 'rpy' or 'quaternion', not both")
        if self.quaternion is not None:
            if set(self.quaternion) != {"x", "y", "z", "w"}:
                raise ValueError("a quaternion needs x, y, z and w")
            if sum(v * v for v in self.quaternion.values()) < 1e-12:
                raise ValueError("the quaternion must not be zero")
        return self


class SimulationSettings(_Strict):
    """Closure simulation settings: ``timestep`` [s], ``sample_period`` [s] between recorded frames."""

    timestep: float = Field(0.002, gt=0.0, le=0.01)
    sample_period: float = Field(0.01, gt=0.0, le=1.0)
    gravity: bool = False
    integrator: Literal["Euler", "RK4", "implicit", "implicitfast"] = "implicitfast"
    surface_points: int = Field(1500, ge=0, le=20000, description="target number of tracked surface points")


class PhysicalParameters(_Strict):
    """Physical parameters echoed for users; the simulation reads the model, these are for the record."""

    joint_stiffness: dict[str, float] = Field(default_factory=dict, description="[N·m/rad] or [N/m] per joint group")
    synergy: dict[str, float] = Field(default_factory=dict, description="transmission coefficients R per joint group")
    actuator_stiffness: float | None = Field(None, description="actuator stiffness Kz in synergy units")
    mass: float | None = Field(None, gt=0.0, description="total hand mass [kg]")
    notes: str = ""


class HandManifest(_Strict):
    """The validated content of a ``hand.toml``."""

    name: str = Field(pattern=NAME_PATTERN)
    description: str = ""
    kind: Literal["underactuated", "soft", "fully_actuated"] = "underactuated"
    model: str
    scene: str | None = None
    mount: str = Field(min_length=1, description="body the hand frame is fixed to (mounted at UR5 tool0)")
    mount_pose: MountPose | None = None
    grasp_frame: MountPose | None = Field(
        None,
        description="the grasp frame's pose in the hand (flange) frame: +z the approach out of the palm, +x across "
        "it; default: the hand frame itself. Plans and closure signatures are in the grasp frame, the arm's IK at "
        "the flange",
    )
    xacro_args: dict[str, str | bool | int | float] = Field(default_factory=dict)
    reference_points: list[ReferencePoint] | None = None
    knuckle: ReferencePoint | None = Field(
        None,
        description="the hand's knuckle point on the palm face (a site, or a body and offset), read at the open "
        "posture: the point placement 'knuckle' puts over the object's centre (the bounding-box planner's rule)",
    )
    closure: Closure
    simulation: SimulationSettings = Field(default_factory=SimulationSettings)
    physical: PhysicalParameters = Field(default_factory=PhysicalParameters)
    calibration: CalibrationSection | None = Field(
        None,
        description="parameters a calibration may move (ranges and sources) and, for a calibrated variant, the "
        "values applied (softsig_service.hands.calibration)",
    )

    @field_validator("model", "scene")
    @classmethod
    def _relative_model_path(cls, value: str | None) -> str | None:
        if value is None:
            return value
        if not value.lower().endswith(MODEL_SUFFIXES):
            raise ValueError(f"model files must end with one of {', '.join(MODEL_SUFFIXES)}")
        return value

    @field_validator("reference_points")
    @classmethod
    def _unique_points(cls, value: list[ReferencePoint] | None) -> list[ReferencePoint] | None:
        if value is None:
            return value
        names = [p.name for p in value]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"reference point names must be unique; repeated: {dup}")
        if len(value) < 4:
            raise ValueError("at least 4 reference points are needed for a closure signature")
        return value

    @model_validator(mode="after")
    def _xacro_args_need_xacro(self) -> HandManifest:
        if self.xacro_args and self.model_format != "xacro":
            raise ValueError("'xacro_args' apply to a .xacro model only")
        return self

    @property
    def model_format(self) -> Literal["mjcf", "urdf", "xacro"]:
        """``"urdf"`` for a ``.urdf`` model file, ``"xacro"`` for a ``.xacro`` one (expanded to URDF), else
        ``"mjcf"``."""
        name = self.model.lower()
        return "urdf" if name.endswith(".urdf") else "xacro" if name.endswith(".xacro") else "mjcf"

    def xacro_mappings(self) -> dict[str, str]:
        """``xacro_args`` as the strings xacro reads (booleans as ``true``/``false``)."""
        return {k: (str(v).lower() if isinstance(v, bool) else str(v)) for k, v in self.xacro_args.items()}


def _loc_to_field(loc: tuple[int | str, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in ("actuator", "posture", "synergy") and out.endswith("closure"):
            continue  # discriminated-union tag, not a field of the document
        else:
            out += ("." if out else "") + str(part)
    return out or "$"


_LITERAL_CHOICES = re.compile(r"'([^']+)'")


def manifest_from_dict(data: Any, *, source: str = "hand.toml") -> HandManifest:
    """Validate a parsed manifest mapping; raise :class:`InvalidManifest` naming the first bad field."""
    try:
        return HandManifest.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        field = _loc_to_field(tuple(err["loc"]))
        choices: list[str] | None = None
        ctx = err.get("ctx") or {}
        if err["type"] == "literal_error" and "expected" in ctx:
            choices = _LITERAL_CHOICES.findall(str(ctx["expected"]))
        elif err["type"] == "union_tag_invalid" and "expected_tags" in ctx:
            choices = _LITERAL_CHOICES.findall(str(ctx["expected_tags"]))
            field = f"{field}.kind" if not field.endswith("kind") else field
        elif err["type"] == "extra_forbidden":
            parent = tuple(err["loc"][:-1])
            choices = _known_fields(parent)
        value = err.get("input") if err["type"] != "missing" else None
        if isinstance(value, dict):
            value = None
        raise InvalidManifest(f"{source}: {err['msg']}", field=field, value=value, choices=choices) from None


def _known_fields(parent: tuple[int | str, ...]) -> list[str] | None:
    model: type[BaseModel] = HandManifest
    sub: dict[str, type[BaseModel]] = {
        "reference_points": ReferencePoint,
        "simulation": SimulationSettings,
        "physical": PhysicalParameters,
        "mount_pose": MountPose,
        "calibration": CalibrationSection,
    }
    names = [p for p in parent if isinstance(p, str)]
    if not names:
        return sorted(model.model_fields)
    if names[0] == "closure":
        kind = names[1] if len(names) > 1 else "actuator"
        kinds: dict[str, type[BaseModel]] = {"posture": PostureClosure, "synergy": SynergyClosure}
        return sorted(kinds.get(kind, ActuatorClosure).model_fields)
    if names[0] in sub:
        return sorted(sub[names[0]].model_fields)
    return None


def load_manifest(path: Path, *, max_bytes: int = 2_000_000) -> HandManifest:
    """Read and validate ``hand.toml`` at ``path``."""
    if not path.is_file():
        raise InvalidManifest("manifest file not found", field="path", value=path.name)
    if path.stat().st_size > max_bytes:
        raise InvalidManifest(f"manifest larger than {max_bytes} bytes", field="path", value=path.stat().st_size)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InvalidManifest(f"{path.name} is not valid TOML: {exc}", field="$") from None
    return manifest_from_dict(data, source=path.name)
