"""Simulated free-space closure of a hand in MuJoCo: wrist fixed, gravity off by default, deterministic.

The closure command ramps linearly from the manifest's open to its closed value over ``duration`` [s] and is
then held for ``settle`` [s]. Reference points (and optionally dense surface points) are recorded every
``sample_period`` [s] in the hand frame (the mount body's frame), starting with the open hand at t = 0.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import SolverError
from softsig_service.hands.model import HandModel, PointSpec
from softsig_service.hands.surface import hand_surface_samples
from softsig_service.hands.trajectory import ClosureTrajectory


def reference_points_world(hand: HandModel, data: mujoco.MjData) -> NDArray[np.float64]:
    """Current world positions [m] of the hand's reference points, shape (N, 3)."""
    out = np.empty((len(hand.points), 3))
    for k, p in enumerate(hand.points):
        out[k] = point_world(p, data)
    return out


def point_world(p: PointSpec, data: mujoco.MjData) -> NDArray[np.float64]:
    """The current world position [m] of one manifest point (a site, or a body plus its offset)."""
    if p.kind == "site":
        return np.array(data.site_xpos[p.id])
    return np.asarray(data.xpos[p.id] + data.xmat[p.id].reshape(3, 3) @ np.asarray(p.offset))


def open_point(hand: HandModel, p: PointSpec) -> NDArray[np.float64]:
    """Where the manifest point ``p`` is at the open posture [m], in the grasp frame (the hand frame unless the
    manifest gives a ``grasp_frame``)."""
    data = prepare_data(hand, hand.model)
    in_hand = to_hand_frame(hand, data, point_world(p, data))
    T_HG = hand.grasp_frame
    return np.asarray((in_hand - T_HG[:3, 3]) @ T_HG[:3, :3])


def to_hand_frame(hand: HandModel, data: mujoco.MjData, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Express world points (..., 3) [m] in the hand (mount) frame."""
    R = data.xmat[hand.mount_body].reshape(3, 3)
    return (points - data.xpos[hand.mount_body]) @ R


def in_grasp_frame(hand: HandModel, traj: ClosureTrajectory) -> ClosureTrajectory:
    """``traj`` (reference points in the hand frame [m]) expressed in the hand's grasp frame (the manifest's
    ``grasp_frame``, ``T_HG``): the frame plans and closure signatures use. The same trajectory when they coincide."""
    T = hand.grasp_frame
    if np.array_equal(T, np.eye(4)):
        return traj
    R, t = T[:3, :3], T[:3, 3]
    surface = None if traj.surface is None else (traj.surface - t) @ R
    return dataclasses.replace(traj, positions=(traj.positions - t) @ R, surface=surface, frame_id="grasp")


def closure_command(hand: HandModel, t: float, duration: float) -> NDArray[np.float64]:
    """The closure controls at time ``t`` [s]: a linear ramp from open to closed over ``duration`` [s]."""
    s = min(max(t / duration, 0.0), 1.0)
    return hand.closure_open + s * (hand.closure_closed - hand.closure_open)


def prepare_data(hand: HandModel, model: mujoco.MjModel) -> mujoco.MjData:
    """A fresh ``MjData`` at the open posture with the open closure command applied."""
    data = mujoco.MjData(model)
    for adr, value in hand.posture_qpos:
        data.qpos[adr] = value
    data.ctrl[list(hand.closure_actuators)] = hand.closure_open
    mujoco.mj_forward(model, data)
    return data


def run_closure(
    hand: HandModel,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    *,
    duration: float,
    settle: float,
    every: int = 0,
    on_sample: Callable[[], None] | None = None,
) -> None:
    """Step ``data`` through the closure ramp and hold; call ``on_sample`` every ``every`` steps and at the end.

    Raises :class:`SolverError` if the simulation diverges (non-finite state or a MuJoCo warning).
    """
    n_steps = round((duration + settle) / model.opt.timestep)
    acts = list(hand.closure_actuators)
    for k in range(1, n_steps + 1):
        data.ctrl[acts] = closure_command(hand, data.time, duration)
        mujoco.mj_step(model, data)
        if on_sample is not None and ((every and k % every == 0) or k == n_steps):
            on_sample()
    warnings = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(data.warning) if w.number}
    if warnings or not np.all(np.isfinite(data.qpos)):
        raise SolverError(
            "closure simulation became unstable",
            field="hand",
            value={"hand": hand.name, "warnings": warnings},
        )


def simulate_closure(
    hand: HandModel,
    *,
    gravity: bool | None = None,
    duration: float | None = None,
    settle: float | None = None,
    sample_period: float | None = None,
    surface_points: int | None = None,
) -> ClosureTrajectory:
    """Close ``hand`` in free space and return its reference-point trajectory in the hand frame.

    Arguments left ``None`` take the manifest's values. ``surface_points`` = 0 skips the dense surface set.
    Raises :class:`SolverError` if the simulation diverges (non-finite state or a MuJoCo warning).
    """
    man = hand.manifest
    duration = man.closure.duration if duration is None else duration
    settle = man.closure.settle if settle is None else settle
    period = man.simulation.sample_period if sample_period is None else sample_period
    n_surface = man.simulation.surface_points if surface_points is None else surface_points
    use_gravity = man.simulation.gravity if gravity is None else gravity

    model = copy.copy(hand.model)
    if not use_gravity:
        model.opt.gravity[:] = 0.0
    data = prepare_data(hand, model)
    every = max(1, round(period / model.opt.timestep))
    geom_idx, local = hand_surface_samples(model, n_surface)

    times: list[float] = [0.0]
    pos: list[NDArray[np.float64]] = [to_hand_frame(hand, data, reference_points_world(hand, data))]
    surf: list[NDArray[np.float64]] = []

    def record_surface() -> None:
        if len(geom_idx):
            R = data.geom_xmat[geom_idx].reshape(-1, 3, 3)
            world = data.geom_xpos[geom_idx] + np.einsum("nij,nj->ni", R, local)
            surf.append(to_hand_frame(hand, data, world))

    record_surface()

    def record() -> None:
        times.append(float(data.time))
        pos.append(to_hand_frame(hand, data, reference_points_world(hand, data)))
        record_surface()

    run_closure(hand, model, data, duration=duration, settle=settle, every=every, on_sample=record)
    return ClosureTrajectory(
        hand=hand.name,
        times=np.asarray(times),
        point_names=hand.point_names,
        positions=np.stack(pos),
        surface=np.stack(surf) if surf else None,
    )
