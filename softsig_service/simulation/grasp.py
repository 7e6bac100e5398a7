"""A power grasp of an object in MuJoCo (docs/design.md §5).

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


The scene and the object's placement: :mod:`softsig_service.simulation.grasp_scene`; the grasp's matrices:
:mod:`softsig_service.simulation.grasp_matrices`.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any, TypedDict

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.config import Settings
from softsig_service.errors import InvalidInput, SolverError
from softsig_service.geometry.quaternions import matrix_to_quat, quat_normalize, quat_to_matrix
from softsig_service.hands.closure import prepare_data, run_closure
from softsig_service.hands.model import HandModel
from softsig_service.objects import TableObject
from softsig_service.simulation.grasp_contacts import contact_forces, net_contact_wrench
from softsig_service.simulation.grasp_scene import compile_with_object, placement_target, resolve_object
from softsig_service.simulation.grasp_state import (
    OBJECT_BODY,
    SUPPORT_AVERAGE,
    TOP_GRASP_ORIENTATION,
    Grasp,
    GraspSettings,
)

FloatArray = NDArray[np.float64]


class GraspOptions(TypedDict, total=False):
    """Options of :func:`grasp_object` and :func:`~softsig_service.simulation.stiffness_signature.find_power_grasp`;
    each may be left out or None (see :func:`grasp_object`)."""

    center: ArrayLike | None
    orientation: ArrayLike | None
    settings: GraspSettings | None
    app_settings: Settings | None


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
            :data:`TOP_GRASP_ORIENTATION` in the grasp frame (the hand frame's, for a hand whose manifest gives no
            ``grasp_frame``).
        settings: grasp settings.

    Raises:
        InvalidInput: a bad ``center``/``orientation``, or an explicit centre where the object overlaps the
            open hand.
        SolverError: no collision-free placement, an unstable simulation, an object that does not settle or is
            not held.
    """
    settings = settings or GraspSettings()
    the_obj = resolve_object(obj)
    R_HG = np.asarray(hand.grasp_frame, dtype=np.float64)[:3, :3]
    if orientation is None:  # a top grasp in the grasp frame, expressed in the hand frame
        quat = matrix_to_quat(R_HG @ quat_to_matrix(TOP_GRASP_ORIENTATION))
    else:
        quat = quat_normalize(orientation, "orientation")
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
        start = _search_free(model, data, geom, put, target, R_HG[:, 2], settings)
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
            wrenches.append(net_contact_wrench(model, data, geom, body))

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
    touching = any(True for _ in contact_forces(model, data, geom, body))
    return settled and touching, speed, ang


def _search_free(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    geom: int,
    put: Any,
    target: FloatArray,
    approach: FloatArray,
    settings: GraspSettings,
) -> FloatArray:
    """The first centre ``target + t a`` (t = 0, step, 2 step...; ``a`` the grasp frame's +z in the hand frame,
    out of the palm) where the object clears the open hand."""
    n = math.floor(settings.search_distance / settings.search_step) + 1
    ez = np.asarray(approach, dtype=np.float64)
    for k in range(n):
        c = target + k * settings.search_step * ez
        put(c)
        if not _overlap(model, data, geom, settings.clearance):
            return c
    raise SolverError(
        "no collision-free placement of the object along the grasp frame's +z from the target",
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
