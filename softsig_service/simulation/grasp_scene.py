"""Scene of a power grasp in MuJoCo: the hand plus the object as a free body, and where the object goes.

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
open hand, pushed along the grasp frame's +z (the approach direction, docs/design.md §3: out of the palm, toward the
object; the hand frame's +z for a hand whose manifest gives no ``grasp_frame``) in
steps of :attr:`GraspSettings.search_step` until it clears the open hand by :attr:`GraspSettings.clearance`.
An explicit ``center`` [m] (hand frame) is used as given, and must not overlap the open hand. The object's
orientation defaults to :data:`TOP_GRASP_ORIENTATION` in the grasp frame (a top grasp: the object's z up = grasp
-z, its x (major axis) along grasp x, so its y (the narrow side of a box) lies along the hand's closing y),
expressed in the hand frame.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.config import Settings, default_settings
from softsig_service.errors import InvalidInput, SolverError
from softsig_service.geometry.quaternions import matrix_to_quat
from softsig_service.hands.closure import simulate_closure
from softsig_service.hands.model import HandModel, compile_hand
from softsig_service.objects import TableObject, builtin_object, object_from_json
from softsig_service.simulation.grasp_state import (
    MOVING_POINT_THRESHOLD,
    OBJECT_BODY,
)
from softsig_service.simulation.object_geom import set_object_shape

FloatArray = NDArray[np.float64]


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
    limits = (settings or default_settings()).limits
    return compile_hand(
        hand.manifest, hand.folder, limits, edit=lambda spec: _add_object(spec, obj), excluded=hand.excluded
    )


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
