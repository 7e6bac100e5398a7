"""The stiffness signature of a hand (docs/design.md §5): find a power grasp of an object
in MuJoCo, compute its 6x6 grasp stiffness and, optionally, its break forces by the pull test
(:mod:`softsig_service.simulation.pullout`).

The grasp stiffness ``K`` is not taken at the wrist: it is expressed in the hand frame (the mount body's frame,
origin at the flange, docs/design.md §3) with the **object's centre** as the reference point (its body origin,
which is its centre of mass, in the settled grasp; ``parameters["reference_point"] == "object centre"``), see
:mod:`softsig_service.simulation.grasp_matrices` and :mod:`softsig_service.signatures.stiffness`. Rows and columns
are linear then angular: a small object displacement ``u = (dx [m], dtheta [rad])`` about that centre gives the
restoring wrench ``-K u`` (force [N], torque [N·m] about the centre), so the blocks are in [N/m], [N] and
[N·m/rad]; the principal stiffnesses depend on that reference point. Pull directions and break forces [N] are in
the hand frame too; the pull force acts on the object's centre.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from typing_extensions import Unpack

from softsig_service.config import Settings
from softsig_service.errors import InvalidInput
from softsig_service.hands.model import HandModel
from softsig_service.objects import TableObject
from softsig_service.signatures.stiffness import principal_stiffnesses
from softsig_service.signatures.stiffness_types import (
    DEFAULT_CONTACT_STIFFNESS,
    TRANSMISSIONS,
    StiffnessSignature,
    Transmission,
)
from softsig_service.simulation.grasp import GraspOptions, grasp_object
from softsig_service.simulation.grasp_matrices import (
    grasp_matrices,
    grasp_stiffness_from_matrices,
    hand_object_contacts,
)
from softsig_service.simulation.grasp_state import DEFAULT_TRANSMISSION, Grasp, GraspSettings
from softsig_service.simulation.pullout import (
    PullSettings,
    check_directions,
    default_directions,
    pull_tests,
)

FloatArray = NDArray[np.float64]


POWER_GRASP_OFFSETS: tuple[tuple[float, float], ...] = (
    (0.0, -0.015), (0.0, 0.015), (0.0, -0.03), (0.0, 0.03),
    (-0.01, 0.0), (0.01, 0.0), (-0.01, -0.015), (0.01, -0.015), (-0.01, 0.015), (0.01, 0.015),
)  # fmt: skip
"""(x, y) offsets [m] in the hand frame around the automatic placement, tried in order when it is not held."""
MAX_LIFT_STEPS = 40
"""How many steps of ``GraspSettings.search_step`` along +z a shifted placement may take to clear the open hand."""


MIN_GRASP_EXTENT = 0.002
"""[m] the smallest largest-extent of an object a stiffness signature is computed on (approximate). Closing on cubes
of 2, 5, 10 and 20 mm, the built-in parallel gripper and SoftHand touch every one, the RBO Hand 2 those from 5 mm
and the SDM Hand those from 10 mm; nothing touches a 0.1 mm cube. Smaller objects are refused before any
simulation; a hand that closes on a larger one without touching it fails the job, naming the object."""


def check_graspable(obj: TableObject) -> None:
    """Refuse (:class:`InvalidInput`, field ``object``) an object too small to be grasped (``MIN_GRASP_EXTENT``)."""
    size = 2.0 * float(np.max(obj.half_extents))
    if not size >= MIN_GRASP_EXTENT:
        raise InvalidInput(
            f"the object is {size * 1000:.3g} mm at its largest; a grasp needs at least {MIN_GRASP_EXTENT * 1000:g} mm",
            field="object",
            value=size,
        )


def find_power_grasp(
    hand: HandModel, obj: TableObject | str | Mapping[str, Any], **options: Unpack[GraspOptions]
) -> Grasp:
    """A power grasp found in MuJoCo: the automatic placement, else the first nearby placement the hand holds.

    ``options`` are those of :func:`grasp_object` (:class:`GraspOptions`). With an explicit ``center`` this is
    :func:`grasp_object`. Otherwise the automatic placement is tried first; if the hand does not hold the object
    alone there, the placement is shifted in the palm plane (the grasp frame's x and y) by
    :data:`POWER_GRASP_OFFSETS` (each raised along the grasp frame's +z until it clears the open hand) and the first
    held grasp is returned. If none holds, the automatic (not held) grasp is returned and says so (``held`` False).
    """
    first = grasp_object(hand, obj, **options)
    if options.get("center") is not None or first.held:
        return first
    step = (options.get("settings") or GraspSettings()).search_step
    R_HG = np.asarray(hand.grasp_frame, dtype=np.float64)[:3, :3]
    for dx, dy in POWER_GRASP_OFFSETS:
        c = first.initial_center + R_HG @ np.array([dx, dy, 0.0])
        for _ in range(MAX_LIFT_STEPS):
            try:
                grasp = grasp_object(hand, obj, **{**options, "center": c})
            except InvalidInput:
                c = c + R_HG[:, 2] * (4 * step)  # overlaps the open hand: move out of the palm
                continue
            if grasp.held:
                return grasp
            break
    return first


def compute_stiffness_signature(
    hand: HandModel,
    obj: TableObject | str | Mapping[str, Any] = "apple",
    *,
    center: ArrayLike | None = None,
    orientation: ArrayLike | None = None,
    directions: ArrayLike | None = None,
    pull: bool = True,
    contact_stiffness: float = DEFAULT_CONTACT_STIFFNESS,
    tangential_ratio: float = 1.0,
    transmission: Transmission = DEFAULT_TRANSMISSION,
    grasp_settings: GraspSettings | None = None,
    pull_settings: PullSettings | None = None,
    app_settings: Settings | None = None,
) -> StiffnessSignature:
    """Grasp ``obj`` with ``hand`` in MuJoCo, compute the grasp stiffness and (if ``pull``) the break forces.

    Args:
        hand: the hand. obj: the object (default the built-in apple).
        center, orientation: the object's placement in the hand frame ([m]; quaternion wxyz); None = automatic
            (:mod:`~softsig_service.simulation.grasp`).
        directions: pull directions (n, 3) in the hand frame; None = :func:`default_directions` (26).
        pull: run the pull test (False: ``break_forces`` is empty).
        contact_stiffness: normal contact stiffness ``kn`` [N/m]; ``tangential_ratio``: ``kt / kn``.
        transmission: ``"parallel"`` (default, what MuJoCo simulates) or ``"series"`` (the soft-synergy formula).

    Returns:
        The :class:`StiffnessSignature` (hand frame). ``parameters`` holds every setting, the grasp's state
        (``held``, the closure wrench, settling), the matrices' summary (contacts, saturated actuators, joints at
        limits) and MuJoCo's own secant contact stiffness (normal force / penetration, median over contacts) for
        comparison with ``contact_stiffness``.
    """
    if transmission not in TRANSMISSIONS:
        raise InvalidInput(
            "unknown transmission model", field="transmission", value=transmission, choices=TRANSMISSIONS
        )
    pull_settings = pull_settings or PullSettings()
    D = (default_directions() if directions is None else check_directions(directions)) if pull else None
    grasp = find_power_grasp(
        hand, obj, center=center, orientation=orientation, settings=grasp_settings, app_settings=app_settings
    )
    mats = grasp_matrices(grasp)
    if not mats.contacts:
        raise InvalidInput(
            f"the hand closed without touching the object (half-extents "
            f"{', '.join(f'{h:.4g}' for h in grasp.object.half_extents)} m): no grasp, no grasp stiffness",
            field="object",
        )
    terms = grasp_stiffness_from_matrices(
        mats, contact_stiffness=contact_stiffness, tangential_ratio=tangential_ratio, transmission=transmission
    )
    breaks = pull_tests(grasp, D, pull_settings) if D is not None else ()
    pt, pr = principal_stiffnesses(terms.K)
    parameters: dict[str, Any] = {
        "contact_stiffness": float(contact_stiffness),
        "tangential_ratio": float(tangential_ratio),
        "contact_model": "hard finger (3-D point contact force)",
        "transmission": transmission,
        "reference_point": "object centre",
        "gravity": False,
        "timestep": float(grasp.model.opt.timestep),
        "grasp": {
            **grasp.settings.to_json_dict(),
            "held": bool(grasp.held),
            "closure_wrench": [float(x) for x in grasp.closure_wrench],
            "settle_time": grasp.settle_time,
            "residual_speed": grasp.residual_speed,
        },
        "matrices": mats.summary(),
        "mujoco_contact_stiffness_median": _mujoco_contact_stiffness(grasp),
        "pull": {
            **pull_settings.to_json_dict(),
            "skipped_not_held": bool(pull and not grasp.held),
            "directions": "default (26: axes, edges, corners)"
            if pull and directions is None
            else ("custom" if pull else "none"),
        },
    }
    return StiffnessSignature(
        K=terms.K,
        principal_translational=pt,
        principal_rotational=pr,
        break_forces=breaks,
        object=grasp.object_description(),
        closure_command=grasp.closure_command(),
        parameters=parameters,
        contacts=tuple(mats.contacts),
        hand=hand.name,
    )


def _mujoco_contact_stiffness(grasp: Grasp) -> float | None:
    """Median over the grasp's contacts of MuJoCo's secant normal stiffness, normal force / penetration [N/m]."""
    values = []
    for i, rec in hand_object_contacts(grasp):
        pen = -float(grasp.data.contact[i].dist)
        if pen > 1e-9:
            values.append(rec.normal_force / pen)
    return float(np.median(values)) if values else None


def break_force_table(ss: StiffnessSignature, names: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """Rows ``{"direction", "force", "capped", "reason"}`` of a signature's break forces (for printing)."""
    rows = []
    for k, b in enumerate(ss.break_forces):
        label = names[k] if names is not None else _direction_label(b.direction)
        rows.append({"direction": label, "force": b.force, "capped": b.capped, "reason": b.reason})
    return rows


def _direction_label(d: ArrayLike) -> str:
    v = np.asarray(d, dtype=np.float64)
    parts = []
    for c, axis in zip(v, "xyz", strict=True):
        if abs(c) > 1e-9:
            parts.append(("+" if c > 0 else "-") + axis)
    return "".join(parts)
