"""The grasped state of a hand and an object in MuJoCo, the settings of the grasp simulation and its constants.

Frames: the hand frame (docs/design.md §3); lengths [m], forces [N], times [s].
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput
from softsig_service.hands.manifest import PostureClosure
from softsig_service.hands.model import HandModel
from softsig_service.objects import TableObject
from softsig_service.signatures.stiffness_types import Transmission

FloatArray = NDArray[np.float64]

OBJECT_BODY = "softsig_object"
"""Name of the object's body (and ``<name>_geom``, ``<name>_joint``) added to the hand's model."""
MOVING_POINT_THRESHOLD = 0.005
"""A reference point that moves more than this [m] in the free closure is a finger point (placement rule)."""
SUPPORT_AVERAGE = 0.1
"""The support wrench is the mean over this last part [s] of the fixture phase (contact chatter)."""
TOP_GRASP_ORIENTATION: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 0.0)
"""Default object orientation in the hand frame, quaternion wxyz: a half turn about x (object z = hand -z,
object x = hand x, object y = hand -y), the pose of a top grasp with the hand +z pointing down."""
DEFAULT_TRANSMISSION: Transmission = "parallel"
"""Transmission model of the simulated hands: actuators act beside the joint springs (see the module docstring)."""


@dataclass(frozen=True)
class GraspSettings:
    """Settings of the simulated grasp.

    Attributes:
        duration: closure ramp [s]; None = the manifest's.
        settle: time [s] the closed command is held before the settling check; None = max(manifest's, 1.0).
        release: time [s] the object is left free after the fixture is removed, before the settling check.
        settle_speed: the object is settled below this linear speed [m/s].
        settle_angular_speed: ... and below this angular speed [rad/s].
        max_extra_settle: at most this much more time [s] to reach the settling speeds (else SolverError).
        clearance: gap [m] between the placed object and the open hand (automatic placement).
        search_step: step [m] of the placement search along hand +z.
        search_distance: the placement search gives up after this distance [m].
        require_hold: raise :class:`SolverError` when the hand does not hold the object alone.
        noslip_iterations: MuJoCo's ``opt.noslip_iterations`` for the grasp and the pull test (module docstring).
    """

    duration: float | None = None
    settle: float | None = None
    release: float = 1.0
    settle_speed: float = 1e-3
    settle_angular_speed: float = 2e-2
    max_extra_settle: float = 3.0
    clearance: float = 0.002
    search_step: float = 0.001
    search_distance: float = 0.3
    require_hold: bool = False
    noslip_iterations: int = 10

    def __post_init__(self) -> None:
        for name in ("settle_speed", "settle_angular_speed", "clearance", "search_step", "search_distance"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise InvalidInput("must be a finite number > 0", field=f"grasp.{name}", value=value)
        for name in ("duration", "settle", "release", "max_extra_settle"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise InvalidInput("must be a finite number >= 0", field=f"grasp.{name}", value=value)
        if not (isinstance(self.noslip_iterations, int) and 0 <= self.noslip_iterations <= 1000):
            raise InvalidInput(
                "must be an integer in 0..1000", field="grasp.noslip_iterations", value=self.noslip_iterations
            )
        if self.duration is not None and self.duration <= 0.0:
            raise InvalidInput("must be > 0", field="grasp.duration", value=self.duration)

    def to_json_dict(self) -> dict[str, Any]:
        """The settings as a JSON dict (None where the manifest's value is used)."""
        return dataclasses.asdict(self)


@dataclass(frozen=True, eq=False)
class Grasp:
    """A settled grasp in MuJoCo. ``data`` is the grasped state; copy it before stepping (``snapshot``).

    Attributes:
        hand: the hand compiled *with* the object (its ``model`` has the object's free body).
        object: the object.
        model: ``hand.model`` with gravity off.
        data: the grasped state.
        object_body, object_geom: ids of the object's body and geom.
        object_qpos: address of the object's free joint in ``qpos`` (position, then quaternion wxyz).
        object_dof: address of its first degree of freedom in ``qvel`` (linear velocity, then angular).
        hand_dofs: ids of the hand's degrees of freedom (every dof but the object's), in model order.
        initial_center: the object's centre [m], hand frame, before the closure.
        center: the object's centre [m], hand frame, in the grasp.
        orientation: the object's initial orientation in the hand frame, quaternion wxyz.
        placement: ``"auto"`` or ``"explicit"``.
        settle_time: simulated time [s] of closure + settling.
        residual_speed: the object's speed [m/s] at the end.
        held: whether the hand holds the object alone (it settled after the release); if not, ``data`` is the
            state at the end of the supported closure (module docstring).
        closure_wrench: (6,) net wrench of the hand's contacts on the held object at the end of the supported
            closure (force [N], torque [N·m] about its centre; hand frame): what the support had to resist.
    """

    hand: HandModel
    object: TableObject
    model: mujoco.MjModel
    data: mujoco.MjData
    object_body: int
    object_geom: int
    object_qpos: int
    object_dof: int
    hand_dofs: NDArray[np.int64]
    initial_center: FloatArray
    center: FloatArray
    orientation: FloatArray
    placement: str
    settle_time: float
    residual_speed: float
    held: bool = True
    closure_wrench: FloatArray = field(default_factory=lambda: np.zeros(6))
    settings: GraspSettings = field(default_factory=GraspSettings)

    def snapshot(self) -> mujoco.MjData:
        """A fresh copy of the grasped state."""
        out = mujoco.MjData(self.model)
        mujoco.mj_copyData(out, self.model, self.data)
        return out

    def hand_rotation(self, data: mujoco.MjData | None = None) -> FloatArray:
        """Rotation (3, 3) of the hand frame in the world of the model."""
        d = self.data if data is None else data
        return np.asarray(d.xmat[self.hand.mount_body].reshape(3, 3).copy())

    def to_hand(self, points: ArrayLike, data: mujoco.MjData | None = None) -> FloatArray:
        """World points (..., 3) [m] of the model expressed in the hand frame."""
        d = self.data if data is None else data
        return np.asarray((np.asarray(points) - d.xpos[self.hand.mount_body]) @ self.hand_rotation(d))

    def object_center(self, data: mujoco.MjData | None = None) -> FloatArray:
        """The object's centre [m] in the hand frame."""
        d = self.data if data is None else data
        return self.to_hand(d.xpos[self.object_body], d)

    def closure_command(self) -> dict[str, Any]:
        """The closure command of the grasp: kind, actuator names and their closed values."""
        model = self.model
        names = [model.actuator(a).name for a in self.hand.closure_actuators]
        closure = self.hand.manifest.closure
        out: dict[str, Any] = {
            "kind": closure.kind,
            "actuators": names,
            "values": [float(v) for v in self.hand.closure_closed],
            "open": [float(v) for v in self.hand.closure_open],
            "duration": float(self.settings.duration or closure.duration),
        }
        if isinstance(closure, PostureClosure):
            out["joints"] = list(closure.closed)
        return out

    def object_description(self) -> dict[str, Any]:
        """JSON description of the object: its spec (without the table pose), the grasped centre [m] and the
        initial orientation (wxyz) in the hand frame, and how it was placed."""
        spec = self.object.to_json()
        spec.pop("pose", None)
        spec["center"] = [float(x) for x in self.center]
        spec["initial_center"] = [float(x) for x in self.initial_center]
        spec["orientation"] = [float(x) for x in self.orientation]
        spec["placement"] = self.placement
        spec["frame_id"] = "hand"
        return spec
