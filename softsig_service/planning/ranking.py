"""Ranked grasp candidates: the alternatives the planner offers beside its strategy's pose, and ``grasp_quality``,
the estimated probability that a grasp carries the object.

Frames: world = UR5 ``base_link`` (z up); flange poses (4x4) with hand +z the approach (down for a top grasp);
lengths [m], angles [rad].

**Alternatives** (the same rule for every object and hand): the strategy's relative yaw and the one that closes
across the other object axis (the major instead of the minor, or for S the hand's +x along the minor axis instead
of the major), each with the placement point over the object's centre and shifted by :data:`SHIFT_FRACTION` of the
object's length either way along its major axis, each in both yaw branches (a half turn apart): up to 12 poses.

**Quality.** With the hand's capture model of the object (strategy R's grid of simulated outcomes,
:mod:`softsig_service.signatures.capture`) it is that model's capture probability at the grasp's relative pose,
averaged over the request's pose noise (``sigma_r``, ``sigma_t``): ``quality_model = "capture"``. Without one it is
the stated geometric model ``"geometric"`` (approximate, no fitted parameter):

    q = |cos(angle between the closure signature's horizontal direction and the object's minor axis)|
        * exp(-(d / (SHIFT_FRACTION * L))^2 / 2)

with ``d`` the horizontal distance from the hand's placement point to the object's centre and ``L`` the object's
major extent: the closure signature closing across the narrow side (the paper's hypothesis, section II) and the hand
centred on the object. A round footprint has no minor axis: its first factor is 1. How well either model predicts
outcomes is measured in docs/planning.md (``softsig experiment ranking``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from softsig_service.objects import TableObject
from softsig_service.planning.strategies import relative_poses
from softsig_service.signatures.capture import CaptureModel, wrap_theta

SHIFT_FRACTION = 0.25
"""The alternatives' placement shifts along the object's major axis, as a fraction of its major extent."""
QUALITY_MODELS: tuple[str, ...] = ("capture", "geometric")


@dataclass(frozen=True)
class Alternative:
    """A candidate flange pose ``T`` (4x4, world; height at the object's centre: the planner descends) and what it
    is: ``theta`` [rad] the relative yaw, ``shift`` [m] of the placement point along the object's major axis,
    ``branch`` 0 or 1 (the yaw branch), ``primary`` whether it is the strategy's own relative yaw unshifted."""

    T: NDArray[np.float64]
    theta: float
    shift: float
    branch: int
    primary: bool

    @property
    def label(self) -> str:
        """A stable, readable id of the candidate (``theta=+0.000,shift=+0.000,branch=0``)."""
        return f"theta={self.theta:+.3f},shift={self.shift:+.3f},branch={self.branch}"


def alternatives(
    obj: TableObject, hand_point: NDArray[np.float64], theta: float, other_theta: float
) -> list[Alternative]:
    """The candidate poses of the module docstring for relative yaws ``theta`` (the strategy's) and ``other_theta``
    [rad], the hand's placement point ``hand_point`` (hand frame) over the object's centre or shifted along its
    major axis; the primary ones first. ``other_theta`` equal to ``theta`` (within 1e-6 rad, modulo a half turn) is
    left out."""
    shift = SHIFT_FRACTION * obj.extent_major
    thetas = [theta]
    if abs(float(wrap_theta(other_theta - theta))) > 1e-6:
        thetas.append(other_theta)
    out: list[Alternative] = []
    for th in thetas:
        for s in (0.0, -shift, shift):
            for branch, T in enumerate(relative_poses(obj.center + s * obj.o1, obj.o1, hand_point, th, 0.0, 0.0)):
                out.append(Alternative(T=T, theta=th, shift=s, branch=branch, primary=th == theta and s == 0.0))
    return out


def relative_pose_of(
    T: NDArray[np.float64], hand_point: NDArray[np.float64], obj: TableObject
) -> tuple[float, float, float]:
    """The relative pose (theta [rad], u, v [m]) of a top-grasp flange pose ``T`` to ``obj``, as
    :func:`~softsig_service.planning.strategies.relative_poses` defines it (its inverse, in the horizontal plane)."""
    R = T[:3, :3]
    x_axis = R[:, 0]
    theta = math.atan2(float(obj.o1[1]), float(obj.o1[0])) - math.atan2(float(x_axis[1]), float(x_axis[0]))
    point = T[:3, :3] @ np.asarray(hand_point, dtype=np.float64) + T[:3, 3]
    d = obj.center - point
    d[2] = 0.0
    return float(wrap_theta(theta)), float(d @ R[:, 0]), float(d @ R[:, 1])


def geometric_quality(
    T: NDArray[np.float64], cs_axis: NDArray[np.float64], hand_point: NDArray[np.float64], obj: TableObject
) -> float:
    """The geometric model's ``q`` in [0, 1] (module docstring) of the flange pose ``T`` for the closure signature
    ``cs_axis`` (hand frame) and the placement point ``hand_point`` (hand frame)."""
    d = T[:3, :3] @ np.asarray(cs_axis, dtype=np.float64)
    d[2] = 0.0
    norm = float(np.linalg.norm(d))
    across = 1.0 if obj.footprint_isotropic or norm < 1e-9 else abs(float(d @ obj.o2)) / norm
    point = T[:3, :3] @ np.asarray(hand_point, dtype=np.float64) + T[:3, 3]
    off = obj.center[:2] - point[:2]
    scale = SHIFT_FRACTION * max(obj.extent_major, 1e-6)
    return float(np.clip(across * math.exp(-0.5 * float(off @ off) / scale**2), 0.0, 1.0))


def grasp_quality(
    T: NDArray[np.float64],
    cs_axis: NDArray[np.float64],
    hand_point: NDArray[np.float64],
    obj: TableObject,
    capture: CaptureModel | None,
    sigma_r: float = 0.0,
    sigma_t: float = 0.0,
) -> tuple[float, str]:
    """(``grasp_quality`` in [0, 1], the model that gave it: ``"capture"`` or ``"geometric"``) of the flange pose
    ``T`` (module docstring); ``sigma_r`` [rad] and ``sigma_t`` [m] the pose noise the capture model averages over."""
    if capture is not None:
        theta, u, v = relative_pose_of(T, hand_point, obj)
        return float(capture.expected(theta, u, v, sigma_r, sigma_t)), "capture"
    return geometric_quality(T, cs_axis, hand_point, obj), "geometric"
