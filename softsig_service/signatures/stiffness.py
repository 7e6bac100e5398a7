"""The stiffness signature (SS) of a grasp: the 6x6 grasp stiffness at the object and the break forces.

Pure math (numpy only, DESIGN §2): no MuJoCo here. :mod:`softsig_service.simulation.grasp` finds a grasp
in MuJoCo and extracts the matrices below; :mod:`softsig_service.simulation.pullout` measures break forces.

**Frames and units.** Every vector and matrix is in the *hand frame* (DESIGN §3: the mount body's frame, +z the
approach). Twists, wrenches and stiffness are ordered linear first, then angular (Pinocchio's order), with the
object's centre as the reference point: a small object displacement ``u = (dx [m], dtheta [rad])`` produces the
restoring wrench ``w = -K u`` = (force [N], torque [N·m]), so ``K`` has blocks in [N/m], [N] (= N·m/m) and
[N·m/rad].

**The formula** (Malvezzi & Prattichizzo, ICRA 2014; the *soft synergy* model)::

    K = G (Kc^-1 + J Kq^-1 J^T + J S Kz^-1 S^T J^T)^-1 G^T

with, for ``nc`` hard-finger contacts (a 3-D force each, no contact torque):

* ``G`` (6 x 3nc) the grasp matrix: block ``G_i = [I_3; [p_i - c]_x]`` maps contact force ``f_i`` (on the
  object, at the contact point ``p_i`` [m]) to the object wrench about the centre ``c`` (:func:`grasp_matrix`);
* ``J`` (3nc x nq) the hand Jacobian: rows 3i..3i+2 give the velocity [m/s] of the hand's material point at
  contact i per joint velocity;
* ``Kq`` (nq x nq) joint stiffness [N·m/rad or N/m]; ``S`` (nq x nz) the synergy (transmission coefficients,
  e.g. a fixed tendon's ``coef``); ``Kz`` (nz x nz) actuator stiffness in synergy units (for a tendon of joint
  coefficients: [N·m per rad of tendon length]); ``Kc`` (3nc x 3nc) contact stiffness [N/m], block diagonal
  (:func:`contact_stiffness_matrix`: ``kn n n^T + kt (I - n n^T)`` per contact, isotropic when ``kt = kn``).

**Two transmission models** (:data:`TRANSMISSIONS`), both computed by :func:`grasp_stiffness`:

* ``"series"`` — the formula above: the actuator sets a reference posture ``q_r = S z`` and the joint springs
  sit *between* it and the joints, so the compliances add: ``Cq = Kq^-1 + S Kz^-1 S^T``. Joint stiffness
  ``Kj = (Kq^-1 + S Kz^-1 S^T)^-1``.
* ``"parallel"`` — the adaptive-synergy / tendon model that MuJoCo simulates for a tendon or a servo acting on
  the joints *beside* their springs: ``tau = -(Kq + S Kz S^T) dq``, so the stiffnesses add:
  ``Kj = Kq + S Kz S^T``. This is the model :mod:`~softsig_service.simulation.grasp` uses by default
  because it is the physics of the simulated hands (a position actuator on a fixed tendon adds
  ``kp gear^2 S S^T`` to the joint stiffness; a posture servo adds ``kp`` on its joint).

**Singular and infinite pieces** (all handled in *stiffness form*, never by inverting a singular matrix;
:func:`hand_quadratic` writes the hand's elastic energy as ``x^T H x / 2`` with constraints ``A x = 0``, where
``x = dq`` for ``"parallel"`` and ``x = (dq, dz)`` — joints and synergy displacements — for ``"series"``):

* A joint of zero stiffness is **free** (no spring transmits force through it), not rigid: the contact-space
  stiffness is computed as ``Kc - Kc J (H + J^T Kc J)^+ J^T Kc`` (Woodbury's identity for
  ``(Kc^-1 + J H^-1 J^T)^-1``; ``J`` has zero columns for the synergy coordinates), exact for a positive definite
  ``H`` and the limit for a singular one. The pseudo-inverse only drops directions ``v`` with ``H v = 0`` *and*
  ``J v = 0`` (motions that neither resist nor move a contact), where it is exact. A **rigid** joint is ``+inf``
  on ``Kq``'s diagonal: a constraint (``dq_j = 0`` in ``"parallel"``; ``dq_j = (S dz)_j`` in ``"series"``, where
  the joint follows its synergy reference rigidly).
* ``Kz = +inf`` (diagonal entry) is a **rigid synergy**: in ``"series"`` ``dz_k = 0``, so its compliance term
  vanishes (the formula without that synergy); in ``"parallel"`` the tendon length is locked, ``S_k^T dq = 0``.
  ``Kz = 0`` is a pure force source (a motor, a pressure, a force-saturated servo): in ``"series"`` ``dz_k`` is
  free (``Kj = Kq - Kq S (S^T Kq S)^+ S^T Kq``), in ``"parallel"`` it adds nothing.
* Equality constraints (``A dq = 0``, e.g. rolling joints: two hinges turning 1:1) restrict the motions to the
  constraint-consistent subspace ``x = P r`` with ``P`` an orthonormal basis of ``null(A)``
  (:func:`constraint_basis`); the hand is then ``J P``, ``P^T H P``. This is exact for a rigid coupling and
  equivalent to treating a coupled pair as one joint of summed stiffness.
* ``Kc`` must be finite and positive definite (a rigid contact on a rigid hand has no finite stiffness).

The contact-space stiffness has its round-off eigenvalues (below :data:`CANCELLATION_RTOL` x the largest contact
stiffness, where the subtraction cancels for a free hand direction) set to 0; ``K = G Kcs G^T`` is then formed
as a Gram matrix and symmetrised, ``(K + K^T) / 2``: positive semidefinite by construction (tested).

**Principal stiffnesses**: the eigen-decompositions of the translational block ``K[:3, :3]`` [N/m] (the force
per unit translation with the rotation held) and of the rotational block ``K[3:, 3:]`` [N·m/rad] (torque per
unit rotation about the object's centre, translation held), values in descending order, directions as rows
(unit vectors in the hand frame) with the sign rule of DESIGN §4 (non-negative x component; if zero, y; if
zero, z). They depend on the reference point (the object's centre).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput

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
PINV_RTOL = 1e-12
"""Relative eigenvalue cut-off of the symmetric pseudo-inverses and null-space bases."""
CANCELLATION_RTOL = 1e-10
"""Eigenvalues of the contact-space stiffness below this fraction of the largest contact stiffness are round-off
of the Woodbury subtraction (a free hand direction) and set to 0."""
SIGN_TOL = 1e-9
"""Component magnitude below which the direction sign rule looks at the next axis."""


# ----------------------------------------------------------------------------------------------------------
# result types
# ----------------------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PrincipalStiffness:
    """Eigen-decomposition of a 3x3 stiffness block: ``values`` (3,) descending [N/m] or [N·m/rad], and
    ``directions`` (3, 3) whose rows are the unit eigenvectors in the hand frame (sign rule of DESIGN §4)."""

    values: FloatArray
    directions: FloatArray

    def to_json_dict(self) -> dict[str, Any]:
        """``{"values": [3], "directions": [[3] x 3]}``."""
        return {"values": _floats(self.values), "directions": [_floats(r) for r in self.directions]}


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
        return {
            "direction": _floats(self.direction),
            "force": float(self.force),
            "capped": bool(self.capped),
            "reason": self.reason,
            "displacement": float(self.displacement),
            "time": float(self.time),
        }


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
        """``{"position" [m], "normal", "force" [N], "normal_force" [N], "hand_body", "hand_geom"}``."""
        return {
            "position": _floats(self.position),
            "normal": _floats(self.normal),
            "force": _floats(self.force),
            "normal_force": self.normal_force,
            "hand_body": self.hand_body,
            "hand_geom": self.hand_geom,
        }


@dataclass(frozen=True, eq=False)
class StiffnessSignature:
    """The stiffness signature of one hand holding one object (DESIGN §5), hand frame.

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
            "K": [_floats(r) for r in self.K],
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


# ----------------------------------------------------------------------------------------------------------
# building blocks
# ----------------------------------------------------------------------------------------------------------


def skew(v: ArrayLike) -> FloatArray:
    """``[v]_x`` (3, 3): ``skew(a) @ b == cross(a, b)``."""
    x, y, z = np.asarray(v, dtype=np.float64)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def grasp_matrix(points: ArrayLike, center: ArrayLike) -> FloatArray:
    """Hard-finger grasp matrix ``G`` (6, 3nc) for contact ``points`` (nc, 3) [m] about ``center`` (3,) [m].

    ``G @ f`` (f = stacked contact forces on the object [N]) is the object wrench (force [N], torque [N·m] about
    the centre). Its transpose maps an object twist (linear, angular) to the contact-point velocities.
    """
    P = _matrix(points, "contacts.position", cols=3)
    c = _vector(center, "object.center", 3)
    G = np.zeros((6, 3 * len(P)))
    for i, p in enumerate(P):
        G[:3, 3 * i : 3 * i + 3] = np.eye(3)
        G[3:, 3 * i : 3 * i + 3] = skew(p - c)
    return G


def contact_stiffness_matrix(
    normals: ArrayLike, normal_stiffness: float = DEFAULT_CONTACT_STIFFNESS, tangential_ratio: float = 1.0
) -> FloatArray:
    """Block-diagonal contact stiffness ``Kc`` (3nc, 3nc) [N/m].

    Per contact: ``kn n n^T + kt (I - n n^T)`` with ``kn = normal_stiffness`` [N/m] and ``kt = tangential_ratio
    * kn``; the default ratio 1 is isotropic (``kn I``, independent of the normals).
    """
    N = _matrix(normals, "contacts.normal", cols=3)
    kn = _positive(normal_stiffness, "contact_stiffness")
    ratio = _positive(tangential_ratio, "tangential_ratio")
    Kc = np.zeros((3 * len(N), 3 * len(N)))
    for i, n in enumerate(N):
        norm = float(np.linalg.norm(n))
        if norm < 1e-12:
            raise InvalidInput("a contact normal is zero", field=f"contacts.normal[{i}]", value=n.tolist())
        nn = np.outer(n, n) / norm**2
        Kc[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = kn * nn + ratio * kn * (np.eye(3) - nn)
    return Kc


def constraint_basis(A: ArrayLike | None, n: int, *, rtol: float = PINV_RTOL) -> FloatArray:
    """Orthonormal basis ``P`` (n, n - rank A) of ``null(A)``: the joint motions ``dq = P r`` with ``A dq = 0``.

    ``A`` (m, n) stacks linearised constraints (rolling-joint couplings, rigid joints, locked tendons); ``None``
    or an empty array gives the identity. Rank by SVD with a relative tolerance ``rtol``.
    """
    if A is None:
        return np.eye(n)
    M = np.asarray(A, dtype=np.float64)
    if M.size == 0:
        return np.eye(n)
    M = M.reshape(-1, n)
    if not np.all(np.isfinite(M)):
        raise InvalidInput("constraint rows must be finite", field="constraints")
    _, s, Vt = np.linalg.svd(M, full_matrices=True)
    rank = int(np.sum(s > rtol * max(float(s[0]) if len(s) else 0.0, 1e-300)))
    return np.ascontiguousarray(Vt[rank:].T)


def hand_quadratic(
    Kq: ArrayLike,
    S: ArrayLike | None = None,
    Kz: ArrayLike | None = None,
    *,
    transmission: Transmission = "series",
) -> tuple[FloatArray, FloatArray]:
    """The hand's elastic energy as a quadratic form ``x^T H x / 2`` and the constraint rows ``A x = 0``.

    ``"parallel"``: ``x = dq`` (nq), ``H = Kq + S Kz S^T``; a synergy with ``Kz = inf`` gives the row ``S_k^T``
    (locked tendon) and a joint with ``Kq = inf`` the row ``e_j^T`` (locked joint).

    ``"series"``: ``x = (dq, dz)`` (nq + nz), the synergy displacements ``dz`` being extra unknowns: energy
    ``(dq - S dz)^T Kq (dq - S dz) / 2 + dz^T Kz dz / 2``. Eliminating ``dz`` gives ``Kj = (Kq^-1 + S Kz^-1
    S^T)^-1`` (the formula's term); a joint with ``Kq = inf`` gives the row ``dq_j - S_j dz = 0`` (the joint
    follows the synergy rigidly), a synergy with ``Kz = inf`` the row ``dz_k = 0`` (its compliance term vanishes).
    ``Kz = 0`` leaves ``dz_k`` free (a force source).

    ``Kz`` left ``None`` with a synergy given means rigid synergies (``inf``). Infinite entries are allowed on
    the diagonals only.
    """
    if transmission not in TRANSMISSIONS:
        raise InvalidInput(
            "unknown transmission model", field="transmission", value=transmission, choices=TRANSMISSIONS
        )
    Kq_m = _square(Kq, "Kq")
    nq = Kq_m.shape[0]
    Kq_fin, rigid_joints = _split_infinite(Kq_m, "Kq")
    if S is None or np.asarray(S).size == 0:
        return _sym(Kq_fin), _rows([np.eye(nq)[j] for j in rigid_joints], nq)
    S_arr = np.asarray(S, dtype=np.float64)
    S_m = S_arr.reshape(nq, 1) if S_arr.ndim == 1 and S_arr.size == nq else _matrix(S_arr, "S")
    if S_m.shape[0] != nq:
        raise InvalidInput(f"S must have {nq} rows (one per joint)", field="S", value=list(S_m.shape))
    nz = S_m.shape[1]
    Kz_m = _square(Kz if Kz is not None else np.full(nz, np.inf), "Kz")
    if Kz_m.shape[0] != nz:
        raise InvalidInput(f"Kz must be {nz} x {nz} (one per synergy)", field="Kz", value=list(Kz_m.shape))
    Kz_fin, rigid_syn = _split_infinite(Kz_m, "Kz")
    if transmission == "parallel":
        rows = [np.eye(nq)[j] for j in rigid_joints] + [S_m[:, k] for k in rigid_syn]
        return _sym(Kq_fin + S_m @ Kz_fin @ S_m.T), _rows(rows, nq)
    n = nq + nz
    H = np.zeros((n, n))
    H[:nq, :nq] = Kq_fin
    H[:nq, nq:] = -Kq_fin @ S_m
    H[nq:, :nq] = -S_m.T @ Kq_fin
    H[nq:, nq:] = S_m.T @ Kq_fin @ S_m + Kz_fin
    rows_s: list[FloatArray] = []
    for j in rigid_joints:
        r = np.zeros(n)
        r[j] = 1.0
        r[nq:] = -S_m[j]
        rows_s.append(r)
    for k in rigid_syn:
        r = np.zeros(n)
        r[nq + k] = 1.0
        rows_s.append(r)
    return _sym(H), _rows(rows_s, n)


def contact_space_stiffness(J: ArrayLike, H: ArrayLike, Kc: ArrayLike, P: ArrayLike | None = None) -> FloatArray:
    """Stiffness seen at the contacts, ``(Kc^-1 + (J P) (P^T H P)^-1 (J P)^T)^-1`` (3nc, 3nc) [N/m].

    ``H`` (n, n) is the hand's stiffness (joint space, possibly augmented by synergy coordinates; ``J`` then has
    zero columns for them) and ``P`` (n, r) a basis of the admissible motions (identity by default). Computed as
    ``Kc - Kc Jr (Hr + Jr^T Kc Jr)^+ Jr^T Kc`` with ``Jr = J P``, ``Hr = P^T H P``: valid for a singular ``Hr``
    (joints with no stiffness are free; directions that neither resist nor move a contact are dropped exactly).
    """
    Kc_m = _square(Kc, "Kc")
    if not np.all(np.isfinite(Kc_m)):
        raise InvalidInput("contact stiffness must be finite", field="contact_stiffness")
    if Kc_m.size and np.linalg.eigvalsh(_sym(Kc_m)).min() <= 0.0:
        raise InvalidInput("contact stiffness must be positive definite", field="contact_stiffness")
    J_m = _matrix(J, "J")
    H_m = _square(H, "H")
    if J_m.shape != (Kc_m.shape[0], H_m.shape[0]):
        raise InvalidInput(
            f"J must be {Kc_m.shape[0]} x {H_m.shape[0]} (3 rows per contact, one column per joint)",
            field="J",
            value=list(J_m.shape),
        )
    P_m = np.eye(H_m.shape[0]) if P is None else _matrix(P, "constraints")
    Jr = J_m @ P_m
    Hr = P_m.T @ H_m @ P_m
    if Jr.shape[1] == 0:
        return _sym(Kc_m)
    inner = Hr + Jr.T @ Kc_m @ Jr
    raw = _sym(Kc_m - Kc_m @ Jr @ psd_pinv(inner) @ Jr.T @ Kc_m)
    # the subtraction cancels where the hand is free: clip its round-off (relative to Kc) to a PSD matrix
    scale = float(np.max(np.abs(np.linalg.eigvalsh(_sym(Kc_m))))) if Kc_m.size else 0.0
    return _psd_clip(raw, CANCELLATION_RTOL * scale)


def grasp_stiffness_terms(
    G: ArrayLike,
    J: ArrayLike,
    Kq: ArrayLike,
    Kc: ArrayLike,
    S: ArrayLike | None = None,
    Kz: ArrayLike | None = None,
    *,
    transmission: Transmission = "series",
    constraints: ArrayLike | None = None,
) -> StiffnessTerms:
    """:func:`grasp_stiffness` with its intermediate products."""
    G_m = _matrix(G, "G")
    if G_m.shape[0] != 6:
        raise InvalidInput("G must have 6 rows (linear then angular)", field="G", value=list(G_m.shape))
    J_m = _matrix(J, "J")
    H, rows = hand_quadratic(Kq, S, Kz, transmission=transmission)
    nq = J_m.shape[1]
    n = H.shape[0]
    if _square(Kq, "Kq").shape[0] != nq:
        raise InvalidInput(f"Kq must be {nq} x {nq} (one per column of J)", field="Kq")
    A = rows
    if constraints is not None and np.asarray(constraints).size:
        C = np.asarray(constraints, dtype=np.float64)
        if C.ndim == 1:
            C = C.reshape(1, -1)
        if C.ndim != 2 or C.shape[1] != nq:
            raise InvalidInput(f"constraint rows must have {nq} columns", field="constraints", value=list(C.shape))
        A = np.vstack([A, np.hstack([C, np.zeros((C.shape[0], n - nq))])])
    P = constraint_basis(A, n)
    J_aug = np.hstack([J_m, np.zeros((J_m.shape[0], n - nq))])
    Kcs = contact_space_stiffness(J_aug, H, Kc, P)
    if Kcs.shape[0] != G_m.shape[1]:
        raise InvalidInput(f"G must have {Kcs.shape[0]} columns (3 per contact)", field="G", value=list(G_m.shape))
    w, V = np.linalg.eigh(Kcs)
    B = G_m @ (V * np.sqrt(np.maximum(w, 0.0)))
    K = _sym(B @ B.T)  # G Kcs G^T as a Gram matrix: PSD to round-off
    return StiffnessTerms(K=K, contact_space=Kcs, hand=H, basis=P)


def grasp_stiffness(
    G: ArrayLike,
    J: ArrayLike,
    Kq: ArrayLike,
    Kc: ArrayLike,
    S: ArrayLike | None = None,
    Kz: ArrayLike | None = None,
    *,
    transmission: Transmission = "series",
    constraints: ArrayLike | None = None,
) -> FloatArray:
    """Grasp stiffness ``K`` (6, 6) at the object's centre, linear then angular, symmetric PSD.

    With the defaults (``"series"``, no constraints) and positive definite ``Kq``, ``Kz``, ``Kc`` this is exactly
    ``G (Kc^-1 + J Kq^-1 J^T + J S Kz^-1 S^T J^T)^-1 G^T``. ``constraints`` (m, nq) are extra rows of
    ``A dq = 0`` (equality couplings). See the module docstring for the units and the singular cases.

    Args:
        G: (6, 3nc) grasp matrix. J: (3nc, nq) hand Jacobian at the contacts.
        Kq: (nq, nq) joint stiffness, or (nq,) its diagonal; ``inf`` on the diagonal = rigid joint.
        Kc: (3nc, 3nc) contact stiffness [N/m], or (3nc,) its diagonal.
        S: (nq, nz) synergy matrix (or (nq,) for one synergy); None = no synergy term.
        Kz: (nz, nz) or (nz,) actuator stiffness; ``inf`` = rigid synergy, 0 = force source.
        transmission: ``"series"`` (the formula) or ``"parallel"`` (``Kq + S Kz S^T``); module docstring.
        constraints: (m, nq) rows ``A`` of linearised equality constraints ``A dq = 0``.
    """
    return grasp_stiffness_terms(G, J, Kq, Kc, S, Kz, transmission=transmission, constraints=constraints).K


def principal_stiffness(block: ArrayLike) -> PrincipalStiffness:
    """Eigen-decomposition of a symmetric 3x3 stiffness block: values descending, unit directions as rows."""
    B = _square(block, "K block")
    if B.shape != (3, 3):
        raise InvalidInput("expected a 3x3 block", field="K", value=list(B.shape))
    w, V = np.linalg.eigh(_sym(B))
    order = np.argsort(-w, kind="stable")
    dirs = np.array([_sign_rule(V[:, k]) for k in order])
    return PrincipalStiffness(values=w[order].copy(), directions=dirs)


def principal_stiffnesses(K: ArrayLike) -> tuple[PrincipalStiffness, PrincipalStiffness]:
    """Principal translational (of ``K[:3, :3]``, [N/m]) and rotational (of ``K[3:, 3:]``, [N·m/rad])
    stiffnesses of a 6x6 grasp stiffness."""
    K_m = _square(K, "K")
    if K_m.shape != (6, 6):
        raise InvalidInput("K must be 6 x 6", field="K", value=list(K_m.shape))
    return principal_stiffness(K_m[:3, :3]), principal_stiffness(K_m[3:, 3:])


def stiffness_ellipsoid(block: ArrayLike, *, force: float = 1.0) -> tuple[FloatArray, FloatArray]:
    """Displacement ellipsoid of a translational block: semi-axes [m] = ``force / values`` along the principal
    directions (the compliance to a unit force; infinite for a zero stiffness). Returns (semi_axes, directions)."""
    ps = principal_stiffness(block)
    with np.errstate(divide="ignore"):
        axes = np.where(ps.values > 0.0, force / np.maximum(ps.values, 1e-300), np.inf)
    return axes, ps.directions


def psd_pinv(M: ArrayLike, *, rtol: float = PINV_RTOL) -> FloatArray:
    """Pseudo-inverse of a symmetric positive semidefinite matrix by eigen-decomposition (relative cut-off)."""
    A = _sym(np.asarray(M, dtype=np.float64))
    if A.size == 0:
        return A.copy()
    w, V = np.linalg.eigh(A)
    cut = rtol * max(float(np.max(np.abs(w))), 1e-300)
    inv = np.where(w > cut, 1.0 / np.where(w > cut, w, 1.0), 0.0)
    return _sym((V * inv) @ V.T)


def is_psd(M: ArrayLike, *, rtol: float = 1e-9) -> bool:
    """Whether ``M`` is symmetric (to ``rtol`` of its largest entry) and has no eigenvalue below
    ``-rtol * max |eigenvalue|``."""
    A = np.asarray(M, dtype=np.float64)
    scale = max(float(np.max(np.abs(A))) if A.size else 0.0, 1e-300)
    if not np.allclose(A, A.T, atol=rtol * scale, rtol=0.0):
        return False
    w = np.linalg.eigvalsh(_sym(A))
    return bool(w.min() >= -rtol * max(float(np.max(np.abs(w))), 1e-300))


# ----------------------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------------------


def _psd_clip(M: FloatArray, tol: float) -> FloatArray:
    """``M`` (symmetric) with its eigenvalues below ``tol`` set to 0."""
    if M.size == 0:
        return M
    w, V = np.linalg.eigh(_sym(M))
    w = np.where(w < tol, 0.0, w)
    return _sym((V * w) @ V.T)


def _sym(M: FloatArray) -> FloatArray:
    return 0.5 * (M + M.T)


def _rows(rows: Sequence[FloatArray], n: int) -> FloatArray:
    return np.array(rows, dtype=np.float64).reshape(-1, n)


def _sign_rule(v: FloatArray) -> FloatArray:
    u = v / np.linalg.norm(v)
    for k in range(3):
        if abs(u[k]) > SIGN_TOL:
            return u if u[k] > 0.0 else -u
    return u


def _split_infinite(M: FloatArray, name: str) -> tuple[FloatArray, list[int]]:
    """Replace +inf diagonal entries by 0 and return their indices; reject NaN, -inf and off-diagonal inf."""
    if np.any(np.isnan(M)):
        raise InvalidInput("NaN in a stiffness matrix", field=name)
    inf = ~np.isfinite(M)
    if not inf.any():
        return M, []
    off = inf & ~np.eye(M.shape[0], dtype=bool)
    if off.any() or np.any(np.diag(M)[np.diag(inf)] < 0):
        raise InvalidInput("only +inf diagonal entries are allowed (a rigid joint or synergy)", field=name)
    idx = [int(i) for i in np.flatnonzero(np.diag(inf))]
    out = M.copy()
    out[idx, :] = 0.0
    out[:, idx] = 0.0
    return out, idx


def _square(M: ArrayLike | None, name: str) -> FloatArray:
    if M is None:
        raise InvalidInput("missing matrix", field=name)
    try:
        A = np.asarray(M, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("expected numbers", field=name) from exc
    if A.ndim == 0:
        A = A.reshape(1, 1)
    elif A.ndim == 1:
        A = np.diag(A)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise InvalidInput("expected a square matrix or a diagonal vector", field=name, value=list(A.shape))
    if np.any(np.isnan(A)):
        raise InvalidInput("NaN in a matrix", field=name)
    finite = np.isfinite(A)
    if np.any(np.diag(A)[np.diag(finite)] < 0.0):
        raise InvalidInput("negative stiffness on the diagonal", field=name)
    A_f = np.where(finite, A, 0.0)
    if not np.allclose(A_f, A_f.T, atol=1e-9 * max(float(np.max(np.abs(A_f))), 1e-300), rtol=0.0):
        raise InvalidInput("a stiffness matrix must be symmetric", field=name)
    return A


def _matrix(M: ArrayLike, name: str, *, cols: int | None = None) -> FloatArray:
    try:
        A = np.asarray(M, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("expected numbers", field=name) from exc
    if cols is not None and A.ndim == 1 and A.size == cols:
        A = A.reshape(1, cols)
    if A.ndim != 2 or (cols is not None and A.shape[1] != cols):
        want = f"(n, {cols})" if cols is not None else "a 2-D array"
        raise InvalidInput(f"expected {want}", field=name, value=list(A.shape))
    if not np.all(np.isfinite(A)):
        raise InvalidInput("NaN or infinite values", field=name)
    return A


def _vector(v: ArrayLike, name: str, n: int) -> FloatArray:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.size != n or not np.all(np.isfinite(a)):
        raise InvalidInput(f"expected {n} finite numbers", field=name, value=a.tolist())
    return a


def _positive(x: float, name: str) -> float:
    try:
        f = float(x)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("expected a number", field=name, value=x) from exc
    if not math.isfinite(f) or f <= 0.0:
        raise InvalidInput("must be a finite number > 0", field=name, value=x)
    return f


def _floats(values: ArrayLike) -> list[float]:
    return [float(x) for x in np.asarray(values, dtype=np.float64).reshape(-1)]
