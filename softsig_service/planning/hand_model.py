"""What the planner needs of a hand, computed once per hand, CS method and criterion: its closure signature, open
reference points, collision shapes and placement points.

Frames and units: the hand frame (= the UR5 flange ``tool0``); lengths in [m].
"""

from __future__ import annotations

import dataclasses
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from softsig_service.arm.shapes import HandShape
from softsig_service.config import Settings
from softsig_service.errors import InvalidInput
from softsig_service.geometry.ellipsoid import mvee
from softsig_service.hands.closure import in_grasp_frame, open_point, simulate_closure
from softsig_service.hands.collision_shapes import hand_collision_shapes
from softsig_service.hands.model import SERVO_PREFIX, load_hand
from softsig_service.signatures.closure import compute_closure_signature
from softsig_service.signatures.closure_types import ClosureSignature, Criterion

Placement = Literal["open_centre", "grasp_centre", "knuckle", "per_strategy", "previous"]
PLACEMENTS: tuple[Placement, ...] = ("open_centre", "grasp_centre", "knuckle", "per_strategy", "previous")
DEPRECATED_PLACEMENTS: dict[str, Placement] = {"previous": "per_strategy"}
"""Old placement names still accepted (for one version), and what they are now called."""
"""Which hand point goes over the object's centre: c_0 of the open hand (both strategies, the default), c_T of
the closed hand (both strategies), the hand's knuckle point on the palm face (both strategies; the manifest's
``knuckle``, the bounding-box planner's rule: its middle-finger knuckle over the box centre), or the previous rule
(S: the open reference points' bounding-box centre; C: the CS anchor)."""
DEFAULT_PLACEMENT: Placement = "open_centre"


@dataclass(frozen=True, eq=False)
class HandPlanningModel:
    """What the planner needs of a hand, computed once: its CS, open reference points and collision shapes, in the
    grasp frame (the hand frame unless the manifest gives a ``grasp_frame``), and where that frame is on the flange.

    Compared and hashed by identity: the planner keys the geometry it derives from a model by the model itself."""

    name: str
    signature: ClosureSignature
    points_open: NDArray[np.float64]
    """(N, 3) [m] open-hand reference points, hand frame."""
    shapes: tuple[HandShape, ...]
    """The open hand's collision primitives posed in the grasp frame (the descent's clearance)."""
    bbox_center: NDArray[np.float64]
    """[m] centre of the open reference points' bounding box, hand frame (strategy S, ``placement="per_strategy"``)."""
    open_centre: NDArray[np.float64]
    """[m] centre c_0 of the open hand's reference-point ellipsoid (MVEE), hand frame."""
    grasp_centre: NDArray[np.float64]
    """[m] centre c_T of the closed hand's reference-point ellipsoid (MVEE), hand frame: where the hand closes to."""
    closure: dict[str, Any]
    flange_shapes: tuple[HandShape, ...] = ()
    """The same primitives posed in the hand (= flange, ``tool0``) frame: the arm's collision world."""
    grasp_in_flange: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    """``T_HG`` (4x4): the grasp frame in the flange frame (the manifest's ``grasp_frame``)."""
    point_names: tuple[str, ...] = ()
    """The reference points' names, in the order of ``points_open``."""
    knuckle: NDArray[np.float64] | None = None
    """[m] the manifest's ``knuckle`` point at the open posture, grasp frame (placement ``"knuckle"``); None if the
    manifest declares none."""

    def placement_point(self, strategy: str, placement: Placement) -> NDArray[np.float64]:
        """The hand-frame point [m] the planner puts over the object's centre for ``strategy`` and ``placement``."""
        if placement == "open_centre":
            return self.open_centre
        if placement == "grasp_centre":
            return self.grasp_centre
        if placement == "knuckle":
            if self.knuckle is None:
                raise InvalidInput(
                    f"placement 'knuckle' needs the hand's knuckle point: hand {self.name!r} declares no 'knuckle' "
                    "in its manifest",
                    field="placement",
                    value=placement,
                )
            return self.knuckle
        return self.signature.anchor if strategy == "C" else self.bbox_center


CACHE_SIZE = 32
"""Planning models kept per process (least recently used first out)."""

_CacheKey = tuple[str, str, "Settings | None", str, str]
"""(hand reference, CS method, settings, criterion, revision): what a model is built from."""
_cache: OrderedDict[_CacheKey, HandPlanningModel] = OrderedDict()
_cache_lock = threading.Lock()


def cached_planning_model(
    hand_ref: str,
    method: str = "ellipsoid",
    settings: Settings | None = None,
    criterion: Criterion = "absolute",
    revision: str = "",
) -> HandPlanningModel | None:
    """The planning model of ``hand_ref`` if this process has built or been given it, else None (nothing is
    simulated). ``revision`` names the hand's content (the registry's ETag of the hand; "" for a folder as it is
    on disk): a replaced hand has another revision, so its old model is never answered for it."""
    key = (hand_ref, method, settings, criterion, revision)
    with _cache_lock:
        model = _cache.get(key)
        if model is not None:
            _cache.move_to_end(key)
        return model


def remember_planning_model(
    model: HandPlanningModel,
    hand_ref: str,
    method: str = "ellipsoid",
    settings: Settings | None = None,
    criterion: Criterion = "absolute",
    revision: str = "",
) -> None:
    """Keep ``model`` (built elsewhere, e.g. in a worker process by :func:`build_planning_model`) for
    :func:`planning_model` with the same arguments."""
    key = (hand_ref, method, settings, criterion, revision)
    with _cache_lock:
        _cache[key] = model
        _cache.move_to_end(key)
        while len(_cache) > CACHE_SIZE:
            _cache.popitem(last=False)


def planning_model(
    hand_ref: str,
    method: str = "ellipsoid",
    settings: Settings | None = None,
    criterion: Criterion = "absolute",
    revision: str = "",
) -> HandPlanningModel:
    """The hand's planning model: cached per hand, CS method, settings, criterion and revision, else built now
    (:func:`build_planning_model`, which simulates the hand's closure) and kept."""
    model = cached_planning_model(hand_ref, method, settings, criterion, revision)
    if model is None:
        model = build_planning_model(hand_ref, method, settings, criterion)
        remember_planning_model(model, hand_ref, method, settings, criterion, revision)
    return model


def _command_name(hand: Any, actuator: int) -> str:
    """What a robot stack commands for a closure actuator: the joint a position servo drives (a posture closure's
    servos are softsig's own), else the actuator itself (a motor or a tendon's force source)."""
    import mujoco

    model = hand.model
    if int(model.actuator_trntype[actuator]) == int(mujoco.mjtTrn.mjTRN_JOINT):
        name = model.actuator(actuator).name
        if name.startswith(SERVO_PREFIX):
            return str(model.joint(int(model.actuator_trnid[actuator][0])).name)
    return str(model.actuator(actuator).name)


def build_planning_model(
    hand_ref: str, method: str = "ellipsoid", settings: Settings | None = None, criterion: Criterion = "absolute"
) -> HandPlanningModel:
    """Simulate the hand's closure once and derive its planning data (no cache; the service runs this in its
    compute pool, with its time limit, and hands the result to :func:`remember_planning_model`)."""
    hand = load_hand(hand_ref, settings)
    traj = in_grasp_frame(hand, simulate_closure(hand, surface_points=800 if method == "mesh" else 0))
    cs = compute_closure_signature(traj, method, criterion=criterion)  # type: ignore[arg-type]
    T_HG = np.asarray(hand.grasp_frame, dtype=np.float64)
    T_GH = np.linalg.inv(T_HG)
    flange_shapes = tuple(hand_collision_shapes(hand))  # posed in the hand (= flange) frame
    P = traj.positions[0]
    closure = {
        "actuators": [hand.model.actuator(a).name for a in hand.closure_actuators],
        "commands": [_command_name(hand, a) for a in hand.closure_actuators],
        "open": hand.closure_open.tolist(),
        "closed": hand.closure_closed.tolist(),
        "duration": hand.manifest.closure.duration,
    }
    return HandPlanningModel(
        name=hand.name,
        signature=cs,
        points_open=P,
        shapes=tuple(dataclasses.replace(sh, pose_in_hand=T_GH @ sh.pose_in_hand) for sh in flange_shapes),
        flange_shapes=flange_shapes,
        grasp_in_flange=T_HG,
        point_names=tuple(traj.point_names),
        bbox_center=(P.min(axis=0) + P.max(axis=0)) / 2,
        open_centre=mvee(P).center,
        grasp_centre=mvee(traj.positions[-1]).center,
        closure=closure,
        knuckle=None if hand.knuckle is None else open_point(hand, hand.knuckle),
    )
