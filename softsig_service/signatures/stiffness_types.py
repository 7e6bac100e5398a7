"""The results of the stiffness signature: principal stiffnesses, break forces, contacts, the signature itself and
the terms of a grasp stiffness. Frames: the hand frame; stiffness [N/m] and [N·m/rad], forces [N].
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from softsig_service.signatures.matrix_checks import float_list, json_fields

FloatArray = NDArray[np.float64]

Transmission = Literal["series", "parallel"]
TRANSMISSIONS: tuple[Transmission, ...] = ("series", "parallel")

DEFAULT_CONTACT_STIFFNESS = 3000.0
"""Default normal contact stiffness ``kn`` [N/m] of a hard-finger contact (isotropic by default, ``kt = kn``).

A round figure of the order of MuJoCo's own secant normal stiffness (normal force / penetration) in the
built-in hands' grasps of the built-in objects (medians 0.7e3 to 3.7e3 N/m for the grasps the hands hold alone;
each stiffness signature reports its own as ``mujoco_contact_stiffness_median``) and of rubber-like finger pads.
Chosen, not fitted to any result. MuJoCo's friction has no elastic (position) term: its tangential resistance
comes from sticking (the noslip solver the grasp simulation turns on), not from a spring, so the isotropic
model's tangential stiffness is a modelling choice (``tangential_ratio``), not a property read from MuJoCo."""
CANCELLATION_RTOL = 1e-10
"""Eigenvalues of the contact-space stiffness below this fraction of the largest contact stiffness are round-off
of the Woodbury subtraction (a free hand direction) and set to 0."""


# ----------------------------------------------------------------------------------------------------------
# result types
# ----------------------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PrincipalStiffness:
    """Eigen-decomposition of a 3x3 stiffness block: ``values`` (3,) descending [N/m] or [N·m/rad], and
    ``directions`` (3, 3) whose rows are the unit eigenvectors in the hand frame (sign rule of docs/design.md §4)."""

    values: FloatArray
    directions: FloatArray

    def to_json_dict(self) -> dict[str, Any]:
        """``{"values": [3], "directions": [[3] x 3]}``."""
        return {"values": float_list(self.values), "directions": [float_list(r) for r in self.directions]}


@dataclass(frozen=True, eq=False)
class BreakForce:
    """The pull-test result for one direction.

    Attributes:
        direction: (3,) unit pull direction in the hand frame.
        force: applied force [N] at the moment the object left the hand, or the cap if it never did; 0 when the
            hand does not hold the object at all.
        capped: True when the object held at the cap (``force`` is then a lower bound).
        reason: ``"displacement"`` (the centre moved beyond the threshold), ``"contact_lost"``, ``"cap"``, or
            ``"not_held"`` (the object leaves the hand with no applied force).
        displacement: distance [m] of the object's centre from its grasped position at that moment.
        time: simulated time [s] of the pull test of this direction.
    """

    direction: FloatArray
    force: float
    capped: bool
    reason: Literal["displacement", "contact_lost", "cap", "not_held"]
    displacement: float = 0.0
    time: float = 0.0

    def to_json_dict(self) -> dict[str, Any]:
        """``{"direction", "force" [N], "capped", "reason", "displacement" [m], "time" [s]}``."""
        return json_fields(self)


@dataclass(frozen=True, eq=False)
class ContactRecord:
    """One hand-object contact of the grasp, hand frame.

    Attributes:
        position: (3,) contact point [m].
        normal: (3,) unit normal pointing from the hand into the object.
        force: (3,) contact force on the object [N] (normal and friction parts).
        hand_body: name of the hand body touching the object (or ``body<id>``).
        hand_geom: name of the hand geom (or ``geom<id>``).
    """

    position: FloatArray
    normal: FloatArray
    force: FloatArray
    hand_body: str
    hand_geom: str

    @property
    def normal_force(self) -> float:
        """Normal component [N] of the contact force (positive = pressing)."""
        return float(self.force @ self.normal)

    def to_json_dict(self) -> dict[str, Any]:
        """``{"position" [m], "normal", "force" [N], "hand_body", "hand_geom", "normal_force" [N]}``."""
        return {**json_fields(self), "normal_force": self.normal_force}


@dataclass(frozen=True, eq=False)
class StiffnessSignature:
    """The stiffness signature of one hand holding one object (docs/design.md §5), hand frame.

    Attributes:
        K: (6, 6) grasp stiffness at the object's centre, linear then angular, symmetric PSD
            (blocks [N/m], [N], [N·m/rad]).
        principal_translational: eigen-decomposition of ``K[:3, :3]`` [N/m].
        principal_rotational: eigen-decomposition of ``K[3:, 3:]`` [N·m/rad].
        break_forces: pull-test results, one per direction (may be empty when the pull test was skipped).
        object: JSON description of the object (shape, mass [kg], friction, grasped centre [m] in the hand frame).
        closure_command: the closure command that made the grasp (actuator names and values).
        parameters: every parameter of the computation (contact stiffness, transmission model, pull settings...).
        contacts: the grasp's hand-object contacts.
        hand: the hand's name.
        frame_id: always ``"hand"``.
    """

    K: FloatArray
    principal_translational: PrincipalStiffness
    principal_rotational: PrincipalStiffness
    break_forces: tuple[BreakForce, ...]
    object: Mapping[str, Any]
    closure_command: Mapping[str, Any]
    parameters: Mapping[str, Any]
    contacts: tuple[ContactRecord, ...] = ()
    hand: str = ""
    frame_id: str = "hand"

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-ready dict with exactly the keys ``K``, ``principal_translational``, ``principal_rotational``,
        ``break_forces``, ``object``, ``frame_id``, ``parameters`` and ``contacts``.

        The hand's name and the closure command are stored in ``parameters`` (``"hand"``,
        ``"closure_command"``).
        """
        params = dict(self.parameters)
        params["hand"] = self.hand
        params["closure_command"] = dict(self.closure_command)
        return {
            "K": [float_list(r) for r in self.K],
            "principal_translational": self.principal_translational.to_json_dict(),
            "principal_rotational": self.principal_rotational.to_json_dict(),
            "break_forces": [b.to_json_dict() for b in self.break_forces],
            "object": dict(self.object),
            "frame_id": self.frame_id,
            "parameters": params,
            "contacts": [c.to_json_dict() for c in self.contacts],
        }


@dataclass(frozen=True, eq=False)
class StiffnessTerms:
    """Intermediate products of :func:`grasp_stiffness` (for inspection and tests).

    Attributes:
        K: (6, 6) grasp stiffness.
        contact_space: (3nc, 3nc) stiffness seen at the contacts, ``(Kc^-1 + J Cq J^T)^-1``.
        hand: (n, n) the hand's stiffness ``H`` of :func:`hand_quadratic` (n = nq, or nq + nz for ``"series"``).
        basis: (n, r) orthonormal basis ``P`` of the admissible motions (constraints applied).
    """

    K: FloatArray
    contact_space: FloatArray
    hand: FloatArray
    basis: FloatArray
