"""A power grasp of an object in MuJoCo, and the matrices of its grasp stiffness (DESIGN §5).

**Scene.** The hand model of :func:`~softsig_service.hands.model.compile_hand` (its ``mount`` body welded to the
world: the hand frame) plus the object as a free body. Gravity is off (the grasp and the pull test measure the
hand, not the object's weight). The object's geom has contact ``priority`` 1 so that the hand-object contacts use
*its* friction (sliding coefficient ``obj.friction``, MuJoCo's default torsional 0.005 and rolling 1e-4) and
``condim = 3``: frictional point contacts, i.e. exactly the hard-finger model of the grasp matrix. It collides
with every hand geom that collides with anything (its ``contype``/``conaffinity`` are the union of the hand's).
The object's mass [kg] is spread uniformly over its shape.

**Where the object goes** (``center`` left ``None``): a free closure of the hand (gravity off, the manifest's
ramp) gives the open and closed positions of the reference points that move by more than
:data:`MOVING_POINT_THRESHOLD` (the fingertips, the jaws). The target is the centroid of their *closed*
positions — where the fingers converge in free space, so every finger closing toward it meets the object (the
midpoint of the open and closed centroids, tried first, leaves the object above the fingers of the palm-facing
hands, which then flick it away). The object is centred there and, if it overlaps the
open hand, pushed along the hand's +z (the approach direction, DESIGN §3: out of the palm, toward the object) in
steps of :attr:`GraspSettings.search_step` until it clears the open hand by :attr:`GraspSettings.clearance`.
An explicit ``center`` [m] (hand frame) is used as given, and must not overlap the open hand. The object's
orientation in the hand frame defaults to :data:`TOP_GRASP_ORIENTATION` (a top grasp: the object's z up = hand
-z, its x (major axis) along hand x, so its y (the narrow side of a box) lies along the hand's closing y).

**Grasp.** From the open posture the closure command ramps to closed over the manifest's ``duration`` and is
held for :attr:`GraspSettings.settle` [s] (default max(manifest's, 1 s)) while the object is *held in place*
(a fixture: its pose is reset and its velocity zeroed after every step, as the table holds an object while a
hand closes on it in a top grasp). Then the object is released: after :attr:`GraspSettings.release` [s] the
simulation continues (closed command held) until the object's speed is below
:attr:`GraspSettings.settle_speed` [m/s] and its angular speed below :attr:`GraspSettings.settle_angular_speed`
[rad/s], for at most :attr:`GraspSettings.max_extra_settle` [s]. If it settles touching the hand, the hand
*holds it alone* (``Grasp.held``) and that is the grasped state. If it does not (it is squeezed out of an open,
non-caging grasp), the grasped state is the end of the supported closure, ``held`` is False (or
:class:`~softsig_service.errors.SolverError` with ``require_hold``), and the net wrench the fixture had to resist
is recorded (``closure_wrench``). MuJoCo's noslip solver (:attr:`GraspSettings.noslip_iterations`, default 10)
is on for the grasp and the pull test: MuJoCo's soft friction otherwise creeps under any tangential load.

**Matrices** (:func:`grasp_matrices`), in the hand frame, about the object's centre (its body origin, which is
its centre of mass):

* contacts: MuJoCo's contact list, hand-object pairs whose normal force (:func:`mujoco.mj_contactForce`)
  exceeds :data:`MIN_CONTACT_FORCE`; point, normal (hand -> object) and force on the object;
* ``G`` (6 x 3nc): :func:`~softsig_service.signatures.stiffness.grasp_matrix` of the contact points;
* ``J`` (3nc x nq): :func:`mujoco.mj_jac` of the hand body of each contact at the contact point, translational
  rows, hand degrees of freedom only (the object's free joint excluded), rotated into the hand frame;
* ``Kq`` (nq x nq): ``model.jnt_stiffness`` per degree of freedom [N·m/rad or N/m], plus passive tendon springs
  ``k_t ten_J^T ten_J`` (they always act beside the joint springs);
* ``S`` (nq x nz), ``Kz`` (nz x nz): one synergy per actuator that moves a hand joint. Column ``S_a = moment_a
  / gear_a`` — for a position actuator on a fixed tendon the tendon's ``coef`` (``ten_J``), for a posture servo
  the unit vector of its joint — and ``Kz_a = k_a gear_a^2`` where ``k_a = -dforce/dlength`` of the actuator
  (``kp`` for a position actuator, ``-biasprm[1]`` for an affine bias; ``-gainprm[1] * input`` added for an
  affine gain). Units: for a fixed tendon of joint coefficients, [N·m per rad of tendon length]; for a servo on
  a slide, [N/m]. A **force-saturated** actuator (at its ``forcerange`` bound) is a constant force: ``k_a = 0``.
  A motor (no bias) has ``k_a = 0``. Other gain/bias types are treated as ``k_a = 0`` and listed.
* constraints ``A`` (m x nq): the Jacobian rows of the active equality constraints (``efc_J`` of the
  ``mjCNSTR_EQUALITY`` rows), e.g. rolling joints (two hinges turning 1:1). The stiffness math restricts the
  joints to ``null(A)`` (the constraint-consistent subspace): a coupled pair behaves as one joint of summed
  stiffness. Soft equality constraints are taken as rigid.
* Joint limits and hand-hand contacts are not part of the linear model (listed in ``parameters``:
  ``joints_at_limit``); nor are MuJoCo's polynomial spring terms (``stiffnesspoly``: only the linear coefficient
  is used; listed as ``nonlinear_springs``).

The transmission model that matches this simulation is ``"parallel"`` (the actuator beside the joint springs,
``Kq + S Kz S^T``), the default of :func:`grasp_stiffness_from_matrices`; ``"series"`` gives the soft-synergy
formula of Malvezzi & Prattichizzo literally (see :mod:`~softsig_service.signatures.stiffness`).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.config import Settings
from softsig_service.errors import InvalidInput, SolverError
from softsig_service.geometry.transforms import matrix_to_quat, quat_normalize, quat_to_matrix
from softsig_service.hands.closure import prepare_data, run_closure, simulate_closure
from softsig_service.hands.manifest import PostureClosure
from softsig_service.hands.model import HandModel, compile_hand
from softsig_service.planning.objects import TableObject, builtin_object, object_from_json
from softsig_service.signatures.stiffness import (
    DEFAULT_CONTACT_STIFFNESS,
    ContactRecord,
    StiffnessTerms,
    Transmission,
    contact_stiffness_matrix,
    grasp_matrix,
    grasp_stiffness_terms,
)
from softsig_service.simulation.object_geom import set_object_shape

FloatArray = NDArray[np.float64]

OBJECT_BODY = "softsig_object"
"""Name of the object's body (and ``<name>_geom``, ``<name>_joint``) added to the hand's model."""
MOVING_POINT_THRESHOLD = 0.005
"""A reference point that moves more than this [m] in the free closure is a finger point (placement rule)."""
SUPPORT_AVERAGE = 0.1
"""The support wrench is the mean over this last part [s] of the fixture phase (contact chatter)."""
MIN_CONTACT_FORCE = 1e-6
"""Hand-object contacts with a normal force at or below this [N] are not part of the grasp."""
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
        return {
            "duration": self.duration,
            "settle": self.settle,
            "release": self.release,
            "settle_speed": self.settle_speed,
            "settle_angular_speed": self.settle_angular_speed,
            "max_extra_settle": self.max_extra_settle,
            "clearance": self.clearance,
            "search_step": self.search_step,
            "search_distance": self.search_distance,
            "require_hold": self.require_hold,
            "noslip_iterations": self.noslip_iterations,
        }


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


@dataclass(frozen=True, eq=False)
class GraspMatrices:
    """The pieces of the grasp stiffness, hand frame, about the object's centre (see the module docstring).

    Attributes:
        contacts: the hand-object contacts (nc of them).
        center: (3,) the object's centre [m].
        G: (6, 3nc) grasp matrix. J: (3nc, nq) hand Jacobian at the contacts.
        Kq: (nq, nq) joint stiffness (with passive tendon springs).
        S: (nq, nz) synergy matrix (one column per actuator moving the hand). Kz: (nz, nz) actuator stiffness.
        constraints: (m, nq) equality-constraint rows ``A`` (``A dq = 0``).
        dof_names: name of each hand dof's joint (nq).
        synergy_names: name of each actuator (nz).
        saturated: actuators at a force limit (``Kz = 0``).
        unmodelled: actuators of a gain/bias type without a stiffness model (``Kz = 0``).
        joints_at_limit: joints whose limit constraint is active (not part of the linear model).
        nonlinear_springs: joints/tendons with MuJoCo's polynomial stiffness terms (only the linear
            coefficient is used).
    """

    contacts: tuple[ContactRecord, ...]
    center: FloatArray
    G: FloatArray
    J: FloatArray
    Kq: FloatArray
    S: FloatArray
    Kz: FloatArray
    constraints: FloatArray
    dof_names: tuple[str, ...]
    synergy_names: tuple[str, ...]
    saturated: tuple[str, ...] = ()
    unmodelled: tuple[str, ...] = ()
    joints_at_limit: tuple[str, ...] = ()
    nonlinear_springs: tuple[str, ...] = ()

    def summary(self) -> dict[str, Any]:
        """JSON summary: sizes, names, the actuator stiffnesses and the flagged actuators/joints."""
        return {
            "n_contacts": len(self.contacts),
            "n_dofs": int(self.Kq.shape[0]),
            "n_constraints": int(self.constraints.shape[0]),
            "synergies": list(self.synergy_names),
            "Kz": [float(x) for x in np.diag(self.Kz)],
            "saturated_actuators": list(self.saturated),
            "unmodelled_actuators": list(self.unmodelled),
            "joints_at_limit": list(self.joints_at_limit),
            "nonlinear_springs": list(self.nonlinear_springs),
        }


# ----------------------------------------------------------------------------------------------------------
# object and placement
# ----------------------------------------------------------------------------------------------------------


def resolve_object(obj: TableObject | str | Mapping[str, Any]) -> TableObject:
    """A :class:`TableObject` from an object, a built-in name (``"apple"``...) or a JSON spec."""
    if isinstance(obj, TableObject):
        return obj
    if isinstance(obj, str):
        return builtin_object(obj)
    if isinstance(obj, Mapping):
        return object_from_json(obj)
    raise InvalidInput(
        "expected an object, a built-in object name or a JSON object spec", field="object", value=type(obj).__name__
    )


def _add_object(spec: mujoco.MjSpec, obj: TableObject) -> None:
    """Add the object as a free body to the hand's spec (collides with every colliding hand geom)."""
    contype = 0
    conaffinity = 0
    for g in spec.geoms:
        contype |= int(g.contype)
        conaffinity |= int(g.conaffinity)
    body = spec.worldbody.add_body(name=OBJECT_BODY)
    body.add_freejoint(name=f"{OBJECT_BODY}_joint")
    prim = obj.primitive()
    T = obj.primitive_in_object
    geom_kwargs: dict[str, Any] = {
        "name": f"{OBJECT_BODY}_geom",
        "pos": T[:3, 3].tolist(),
        "quat": matrix_to_quat(T[:3, :3]).tolist(),
        "mass": float(obj.mass),
        "friction": [float(obj.friction), 0.005, 0.0001],
        "condim": 3,
        "priority": 1,
        "contype": conaffinity or 1,
        "conaffinity": contype or 1,
        "rgba": [0.85, 0.25, 0.2, 1.0],
    }
    set_object_shape(spec, body.add_geom(**geom_kwargs), prim, f"{OBJECT_BODY}_mesh")


def compile_with_object(hand: HandModel, obj: TableObject, settings: Settings | None = None) -> HandModel:
    """The hand recompiled with ``obj`` as a free body named :data:`OBJECT_BODY` (not cached)."""
    limits = (settings or Settings()).limits
    return compile_hand(hand.manifest, hand.folder, limits, edit=lambda spec: _add_object(spec, obj))


def placement_target(hand: HandModel, *, duration: float | None = None) -> tuple[FloatArray, FloatArray]:
    """Target centre [m] of the automatic placement (hand frame) and the finger points' open positions.

    The centroid of the closed positions of the reference points that move more than
    :data:`MOVING_POINT_THRESHOLD` in a free closure (gravity off).
    """
    traj = simulate_closure(hand, gravity=False, duration=duration, surface_points=0)
    P = traj.positions
    moving = np.linalg.norm(P[-1] - P[0], axis=1) > MOVING_POINT_THRESHOLD
    if not moving.any():
        raise SolverError(
            "no reference point moves in the free closure: cannot place the object automatically",
            field="center",
            value=hand.name,
        )
    c_closed = P[-1, moving].mean(axis=0)
    return c_closed, P[0, moving]


def grasp_object(
    hand: HandModel,
    obj: TableObject | str | Mapping[str, Any],
    *,
    center: ArrayLike | None = None,
    orientation: ArrayLike | None = None,
    settings: GraspSettings | None = None,
    app_settings: Settings | None = None,
) -> Grasp:
    """Place ``obj`` in the open ``hand``, close the hand with gravity off and let the grasp settle.

    Args:
        hand: the hand (as loaded by :func:`~softsig_service.hands.model.load_hand`).
        obj: the object (a :class:`TableObject`, a built-in name or a JSON spec); its table pose is ignored.
        center: the object's centre [m] in the hand frame; None = the automatic rule (module docstring).
        orientation: the object's orientation in the hand frame, quaternion wxyz; None =
            :data:`TOP_GRASP_ORIENTATION`.
        settings: grasp settings.

    Raises:
        InvalidInput: a bad ``center``/``orientation``, or an explicit centre where the object overlaps the
            open hand.
        SolverError: no collision-free placement, an unstable simulation, an object that does not settle or is
            not held.
    """
    settings = settings or GraspSettings()
    the_obj = resolve_object(obj)
    quat = quat_normalize(orientation if orientation is not None else TOP_GRASP_ORIENTATION, "orientation")
    explicit = center is not None
    if explicit:
        c = np.asarray(center, dtype=np.float64).reshape(-1)
        if c.size != 3 or not np.all(np.isfinite(c)):
            raise InvalidInput(
                "center must be 3 finite numbers [m] (hand frame)", field="center", value=np.asarray(center).tolist()
            )
    full = compile_with_object(hand, the_obj, app_settings)
    model = copy.copy(full.model)
    model.opt.gravity[:] = 0.0
    model.opt.noslip_iterations = settings.noslip_iterations
    body = int(model.body(OBJECT_BODY).id)
    geom = int(model.geom(f"{OBJECT_BODY}_geom").id)
    joint = int(model.joint(f"{OBJECT_BODY}_joint").id)
    qadr = int(model.jnt_qposadr[joint])
    vadr = int(model.jnt_dofadr[joint])
    data = prepare_data(full, model)
    R = data.xmat[full.mount_body].reshape(3, 3).copy()
    p0 = data.xpos[full.mount_body].copy()
    R_obj = R @ quat_to_matrix(quat)

    def put(center_hand: FloatArray) -> None:
        data.qpos[qadr : qadr + 3] = p0 + R @ center_hand
        data.qpos[qadr + 3 : qadr + 7] = matrix_to_quat(R_obj)
        data.qvel[:] = 0.0

    if explicit:
        start = c
        put(start)
        if _overlap(model, data, geom, 0.0):
            raise InvalidInput(
                "the object overlaps the open hand at the given center", field="center", value=start.tolist()
            )
        placement = "explicit"
    else:
        target, _ = placement_target(hand, duration=settings.duration)
        start = _search_free(model, data, geom, put, target, settings)
        placement = "auto"
    put(start)
    mujoco.mj_forward(model, data)

    closure = full.manifest.closure
    duration = settings.duration or closure.duration
    settle = settings.settle if settings.settle is not None else max(closure.settle, 1.0)
    held_q = data.qpos[qadr : qadr + 7].copy()
    n_avg = max(1, round(SUPPORT_AVERAGE / model.opt.timestep))
    n_total = round((duration + settle) / model.opt.timestep)
    wrenches: list[FloatArray] = []
    step = [0]

    def hold() -> None:  # the fixture: the object stays where it was placed while the hand closes
        data.qpos[qadr : qadr + 7] = held_q
        data.qvel[vadr : vadr + 6] = 0.0
        step[0] += 1
        if step[0] > n_total - n_avg:
            wrenches.append(_net_contact_wrench(model, data, geom, body))

    run_closure(full, model, data, duration=duration, settle=settle, every=1, on_sample=hold)
    mujoco.mj_forward(model, data)
    fixture = mujoco.MjData(model)
    mujoco.mj_copyData(fixture, model, data)

    residual = np.mean(wrenches, axis=0)
    # release: the grasp finds its equilibrium if the hand holds the object alone
    held, speed, _ = _settle(model, data, geom, body, vadr, settings)
    if not np.all(np.isfinite(data.qpos)):
        raise SolverError("the grasp simulation became unstable", field="hand", value=hand.name)
    if not held:
        if settings.require_hold:
            raise SolverError(
                "the hand does not hold the object without support (it leaves the hand when released)",
                field="grasp.require_hold",
                value={
                    "hand": hand.name,
                    "object": the_obj.name,
                    "center": [float(x) for x in start],
                    "residual_force": [float(x) for x in R.T @ residual[:3]],
                },
            )
        mujoco.mj_copyData(data, model, fixture)  # the grasped state is the end of the supported closure
        speed = 0.0
    mujoco.mj_forward(model, data)
    grasp = Grasp(
        hand=full,
        object=the_obj,
        model=model,
        data=data,
        object_body=body,
        object_geom=geom,
        object_qpos=qadr,
        object_dof=vadr,
        hand_dofs=np.array([d for d in range(model.nv) if model.dof_bodyid[d] != body], dtype=np.int64),
        initial_center=np.asarray(start, dtype=np.float64),
        center=np.zeros(3),
        orientation=quat,
        placement=placement,
        settle_time=float(data.time),
        residual_speed=float(speed),
        held=held,
        closure_wrench=np.concatenate([R.T @ residual[:3], R.T @ residual[3:]]),
        settings=settings,
    )
    object.__setattr__(grasp, "center", grasp.object_center())
    return grasp


def _settle(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    geom: int,
    body: int,
    vadr: int,
    settings: GraspSettings,
) -> tuple[bool, float, float]:
    """Step for ``release`` [s], then until the object is slower than the settling speeds (at most
    ``max_extra_settle`` [s]); held = settled with at least one loaded hand-object contact."""
    for _ in range(round(settings.release / model.opt.timestep)):
        mujoco.mj_step(model, data)
    extra_steps = round(settings.max_extra_settle / model.opt.timestep)
    speed, ang = _object_speed(data, vadr)
    k = 0
    while (speed > settings.settle_speed or ang > settings.settle_angular_speed) and k < extra_steps:
        mujoco.mj_step(model, data)
        k += 1
        if k % 10 == 0 or k == extra_steps:
            speed, ang = _object_speed(data, vadr)
    if not np.all(np.isfinite(data.qpos)):
        return False, math.inf, math.inf
    mujoco.mj_forward(model, data)
    settled = speed <= settings.settle_speed and ang <= settings.settle_angular_speed
    touching = any(True for _ in _contact_forces(model, data, geom, body))
    return settled and touching, speed, ang


def _contact_forces(
    model: mujoco.MjModel, data: mujoco.MjData, geom: int, body: int
) -> list[tuple[int, int, FloatArray, FloatArray]]:
    """Loaded hand-object contacts: (contact index, hand geom, force on the object (world) [N], normal into the
    object (world))."""
    out = []
    f6 = np.zeros(6)
    for i in range(data.ncon):
        con = data.contact[i]
        g1, g2 = int(con.geom1), int(con.geom2)
        if geom not in (g1, g2) or con.efc_address < 0:
            continue
        other = g2 if g1 == geom else g1
        other_body = int(model.geom_bodyid[other])
        if other_body in (0, body):
            continue
        mujoco.mj_contactForce(model, data, i, f6)
        frame = con.frame.reshape(3, 3)
        # mj_contactForce: the force geom1 exerts on geom2, in the contact frame (rows: normal, t1, t2; the
        # normal points from geom1 to geom2)
        f_world = frame.T @ f6[:3]
        normal = frame[0].copy()
        if g1 == geom:
            f_world, normal = -f_world, -normal
        if float(f_world @ normal) > MIN_CONTACT_FORCE:
            out.append((i, other, f_world, normal))
    return out


def _net_contact_wrench(model: mujoco.MjModel, data: mujoco.MjData, geom: int, body: int) -> FloatArray:
    """Net wrench (force [N], torque [N·m] about the body's centre of mass; world frame) of the hand's contacts
    on the object."""
    w = np.zeros(6)
    c = data.xipos[body]
    for i, _, f, _ in _contact_forces(model, data, geom, body):
        w[:3] += f
        w[3:] += np.cross(data.contact[i].pos - c, f)
    return w


def _search_free(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    geom: int,
    put: Any,
    target: FloatArray,
    settings: GraspSettings,
) -> FloatArray:
    """The first centre ``target + t e_z`` (t = 0, step, 2 step...) where the object clears the open hand."""
    n = math.floor(settings.search_distance / settings.search_step) + 1
    ez = np.array([0.0, 0.0, 1.0])
    for k in range(n):
        c = target + k * settings.search_step * ez
        put(c)
        if not _overlap(model, data, geom, settings.clearance):
            return c
    raise SolverError(
        "no collision-free placement of the object along the hand's +z from the target",
        field="center",
        value=[float(x) for x in target],
    )


def _overlap(model: mujoco.MjModel, data: mujoco.MjData, geom: int, margin: float) -> bool:
    """Whether the object's geom is within ``margin`` [m] of any geom it collides with, at ``data.qpos``."""
    saved = float(model.geom_margin[geom])
    model.geom_margin[geom] = margin
    try:
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        return any((c.geom1 == geom or c.geom2 == geom) and c.dist < margin for c in data.contact[: data.ncon])
    finally:
        model.geom_margin[geom] = saved


def _object_speed(data: mujoco.MjData, vadr: int) -> tuple[float, float]:
    """Linear [m/s] and angular [rad/s] speed of the free body whose joint's first dof is ``vadr``."""
    v = data.qvel[vadr : vadr + 6]
    return float(np.linalg.norm(v[:3])), float(np.linalg.norm(v[3:]))


# ----------------------------------------------------------------------------------------------------------
# contacts and matrices
# ----------------------------------------------------------------------------------------------------------


def hand_object_contacts(grasp: Grasp, data: mujoco.MjData | None = None) -> list[tuple[int, ContactRecord]]:
    """The loaded hand-object contacts of ``data`` (default: the grasp): (contact index, record), hand frame."""
    d = grasp.data if data is None else data
    model = grasp.model
    R = grasp.hand_rotation(d)
    out: list[tuple[int, ContactRecord]] = []
    for i, other, f_world, normal in _contact_forces(model, d, grasp.object_geom, grasp.object_body):
        body = int(model.geom_bodyid[other])
        out.append(
            (
                i,
                ContactRecord(
                    position=grasp.to_hand(d.contact[i].pos, d),
                    normal=normal @ R,
                    force=f_world @ R,
                    hand_body=model.body(body).name or f"body{body}",
                    hand_geom=model.geom(other).name or f"geom{other}",
                ),
            )
        )
    return out


def grasp_matrices(grasp: Grasp) -> GraspMatrices:
    """Contacts, ``G``, ``J``, ``Kq``, ``S``, ``Kz`` and the equality constraints of the grasp (module
    docstring), hand frame, about the object's centre."""
    model, data = grasp.model, grasp.data
    R = grasp.hand_rotation()
    dofs = grasp.hand_dofs
    nq = len(dofs)
    pairs = hand_object_contacts(grasp)
    contacts = tuple(rec for _, rec in pairs)
    center = grasp.object_center()
    G = grasp_matrix(np.array([c.position for c in contacts]).reshape(-1, 3), center)
    J = np.zeros((3 * len(pairs), nq))
    jacp = np.zeros((3, model.nv))
    for k, (i, _) in enumerate(pairs):
        con = data.contact[i]
        other = int(con.geom2) if int(con.geom1) == grasp.object_geom else int(con.geom1)
        mujoco.mj_jac(model, data, jacp, None, con.pos, int(model.geom_bodyid[other]))
        J[3 * k : 3 * k + 3] = R.T @ jacp[:, dofs]

    jnts = model.dof_jntid[dofs]
    Kq = np.diag(model.jnt_stiffness[jnts].astype(np.float64))
    nonlinear = sorted(
        {model.joint(int(j)).name for j in jnts if np.any(np.asarray(model.jnt_stiffnesspoly[j]) != 0.0)}
        | {
            model.tendon(t).name or f"tendon{t}"
            for t in range(model.ntendon)
            if np.any(np.asarray(model.tendon_stiffnesspoly[t]) != 0.0)
        }
    )
    if model.ntendon:
        tJ = _tendon_jacobian(model, data)[:, dofs]
        for t in range(model.ntendon):
            kt = float(np.asarray(model.tendon_stiffness[t]).reshape(-1)[0])
            if kt > 0.0:
                Kq = Kq + kt * np.outer(tJ[t], tJ[t])

    syn = actuator_synergies(model, data, dofs)
    A = _equality_rows(model, data)[:, dofs]
    return GraspMatrices(
        contacts=contacts,
        center=center,
        G=G,
        J=J,
        Kq=0.5 * (Kq + Kq.T),
        S=syn.S,
        Kz=syn.Kz,
        constraints=A,
        dof_names=tuple(model.joint(int(model.dof_jntid[d])).name for d in dofs),
        synergy_names=syn.names,
        saturated=syn.saturated,
        unmodelled=syn.unmodelled,
        joints_at_limit=_joints_at_limit(model, data),
        nonlinear_springs=tuple(nonlinear),
    )


@dataclass(frozen=True, eq=False)
class ActuatorSynergies:
    """The synergies of a model's actuators (module docstring): ``S`` (nq, nz), ``Kz`` (nz, nz) diagonal, the
    actuator names, and those at a force limit or of an unmodelled type (their ``Kz`` is 0)."""

    S: FloatArray
    Kz: FloatArray
    names: tuple[str, ...]
    saturated: tuple[str, ...]
    unmodelled: tuple[str, ...]


def actuator_synergies(model: mujoco.MjModel, data: mujoco.MjData, dofs: ArrayLike) -> ActuatorSynergies:
    """One synergy per actuator with a non-zero moment on ``dofs``: ``S_a = moment_a / gear_a`` and
    ``Kz_a = k_a gear_a^2`` with ``k_a = -dforce/dlength`` (0 when force-saturated or of an unmodelled type)."""
    idx = np.asarray(dofs, dtype=np.int64)
    moments = _actuator_moments(model, data)[:, idx]
    cols: list[FloatArray] = []
    kz: list[float] = []
    names: list[str] = []
    saturated: list[str] = []
    unmodelled: list[str] = []
    for a in range(model.nu):
        m = moments[a]
        if not np.any(m != 0.0):
            continue
        name = model.actuator(a).name or f"actuator{a}"
        gear = float(model.actuator_gear[a, 0]) or 1.0
        k, modelled = _actuator_length_stiffness(model, data, a)
        if not modelled:
            unmodelled.append(name)
        if _saturated(model, data, a):
            k = 0.0
            saturated.append(name)
        cols.append(m / gear)
        kz.append(max(k, 0.0) * gear * gear)
        names.append(name)
    return ActuatorSynergies(
        S=np.array(cols, dtype=np.float64).T.reshape(len(idx), len(cols)),
        Kz=np.diag(kz) if kz else np.zeros((0, 0)),
        names=tuple(names),
        saturated=tuple(saturated),
        unmodelled=tuple(unmodelled),
    )


def grasp_stiffness_from_matrices(
    mats: GraspMatrices,
    *,
    contact_stiffness: float = DEFAULT_CONTACT_STIFFNESS,
    tangential_ratio: float = 1.0,
    transmission: Transmission = DEFAULT_TRANSMISSION,
) -> StiffnessTerms:
    """The grasp stiffness of the matrices (:func:`~softsig_service.signatures.stiffness.grasp_stiffness_terms`)
    with the contact stiffness ``kn = contact_stiffness`` [N/m], ``kt = tangential_ratio * kn``."""
    normals = np.array([c.normal for c in mats.contacts]).reshape(-1, 3)
    Kc = contact_stiffness_matrix(normals, contact_stiffness, tangential_ratio)
    return grasp_stiffness_terms(
        mats.G,
        mats.J,
        mats.Kq,
        Kc,
        mats.S if mats.S.shape[1] else None,
        mats.Kz if mats.S.shape[1] else None,
        transmission=transmission,
        constraints=mats.constraints,
    )


def _dense(rows: int, cols: int, values: Any, rownnz: Any, rowadr: Any, colind: Any) -> FloatArray:
    """A dense (rows, cols) matrix from MuJoCo's compressed sparse-row arrays."""
    out = np.zeros((rows, cols))
    if rows:
        mujoco.mju_sparse2dense(
            out,
            np.asarray(values, dtype=np.float64),
            np.asarray(rownnz, dtype=np.int32),
            np.asarray(rowadr, dtype=np.int32),
            np.asarray(colind, dtype=np.int32),
        )
    return out


def _actuator_moments(model: mujoco.MjModel, data: mujoco.MjData) -> FloatArray:
    """Dense actuator moment arms (nu, nv) from MuJoCo's sparse ``actuator_moment``."""
    return _dense(model.nu, model.nv, data.actuator_moment, data.moment_rownnz, data.moment_rowadr,
                  data.moment_colind)  # fmt: skip


def _tendon_jacobian(model: mujoco.MjModel, data: mujoco.MjData) -> FloatArray:
    """Dense tendon Jacobian (ntendon, nv) from MuJoCo's sparse ``ten_J``."""
    return _dense(model.ntendon, model.nv, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind)


def _actuator_length_stiffness(model: mujoco.MjModel, data: mujoco.MjData, a: int) -> tuple[float, bool]:
    """``-dforce/dlength`` of actuator ``a`` (force = gain * input + bias) and whether its type is modelled."""
    k = 0.0
    modelled = True
    bias = int(model.actuator_biastype[a])
    if bias == int(mujoco.mjtBias.mjBIAS_AFFINE):
        k -= float(model.actuator_biasprm[a, 1])
    elif bias != int(mujoco.mjtBias.mjBIAS_NONE):
        modelled = False
    gain = int(model.actuator_gaintype[a])
    if gain == int(mujoco.mjtGain.mjGAIN_AFFINE):
        actadr = int(model.actuator_actadr[a])
        u = float(data.act[actadr + int(model.actuator_actnum[a]) - 1]) if actadr >= 0 else float(data.ctrl[a])
        k -= float(model.actuator_gainprm[a, 1]) * u
    elif gain != int(mujoco.mjtGain.mjGAIN_FIXED):
        modelled = False
    return (k, True) if modelled else (0.0, False)


def _saturated(model: mujoco.MjModel, data: mujoco.MjData, a: int) -> bool:
    if not model.actuator_forcelimited[a]:
        return False
    lo, hi = (float(x) for x in model.actuator_forcerange[a])
    f = float(data.actuator_force[a])
    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
    return f <= lo + tol or f >= hi - tol


def _efc_rows(model: mujoco.MjModel, data: mujoco.MjData, rows: NDArray[np.int64]) -> FloatArray:
    if not len(rows):
        return np.zeros((0, model.nv))
    if mujoco.mj_isSparse(model):
        dense = np.zeros((data.nefc, model.nv))
        mujoco.mju_sparse2dense(
            dense,
            np.asarray(data.efc_J, dtype=np.float64),
            np.asarray(data.efc_J_rownnz, dtype=np.int32),
            np.asarray(data.efc_J_rowadr, dtype=np.int32),
            np.asarray(data.efc_J_colind, dtype=np.int32),
        )
    else:
        dense = np.asarray(data.efc_J).reshape(data.nefc, model.nv)
    return np.asarray(dense[rows].copy())


def _equality_rows(model: mujoco.MjModel, data: mujoco.MjData) -> FloatArray:
    rows = np.flatnonzero(np.asarray(data.efc_type[: data.nefc]) == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY))
    return _efc_rows(model, data, rows)


def _joints_at_limit(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[str, ...]:
    types = np.asarray(data.efc_type[: data.nefc])
    force = np.asarray(data.efc_force[: data.nefc])
    ids = np.asarray(data.efc_id[: data.nefc])
    sel = (types == int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT)) & (np.abs(force) > 0.0)
    return tuple(sorted({model.joint(int(j)).name for j in ids[sel]}))
