"""The stiffness signature (SS) of a grasp: the 6x6 grasp stiffness at the object and the break forces.

Pure math (numpy only, docs/design.md §2): no MuJoCo here. :mod:`softsig_service.simulation.grasp` finds a grasp
in MuJoCo and extracts the matrices below; :mod:`softsig_service.simulation.pullout` measures break forces.

**Frames and units.** Every vector and matrix is in the *hand frame* (docs/design.md §3: the mount body's frame, +z the
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
(unit vectors in the hand frame) with the sign rule of :func:`~softsig_service.geometry.pca.orient_axes` (the
largest component positive). They depend on the reference point (the object's centre).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ParamSpec

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput
from softsig_service.geometry.pca import orient_axes
from softsig_service.signatures.matrix_checks import (
    PINV_RTOL,
    checked_matrix,
    checked_positive,
    checked_vector,
    psd_clip,
    psd_pinv,
    rows_array,
    split_infinite,
    square_matrix,
    sym,
)
from softsig_service.signatures.stiffness_types import (
    CANCELLATION_RTOL,
    DEFAULT_CONTACT_STIFFNESS,
    TRANSMISSIONS,
    PrincipalStiffness,
    StiffnessTerms,
    Transmission,
)

FloatArray = NDArray[np.float64]


def skew(v: ArrayLike) -> FloatArray:
    """``[v]_x`` (3, 3): ``skew(a) @ b == cross(a, b)``."""
    x, y, z = np.asarray(v, dtype=np.float64)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def grasp_matrix(points: ArrayLike, center: ArrayLike) -> FloatArray:
    """Hard-finger grasp matrix ``G`` (6, 3nc) for contact ``points`` (nc, 3) [m] about ``center`` (3,) [m].

    ``G @ f`` (f = stacked contact forces on the object [N]) is the object wrench (force [N], torque [N·m] about
    the centre). Its transpose maps an object twist (linear, angular) to the contact-point velocities.
    """
    P = checked_matrix(points, "contacts.position", cols=3)
    c = checked_vector(center, "object.center", 3)
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
    N = checked_matrix(normals, "contacts.normal", cols=3)
    kn = checked_positive(normal_stiffness, "contact_stiffness")
    ratio = checked_positive(tangential_ratio, "tangential_ratio")
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
    Kq_m = square_matrix(Kq, "Kq")
    nq = Kq_m.shape[0]
    Kq_fin, rigid_joints = split_infinite(Kq_m, "Kq")
    if S is None or np.asarray(S).size == 0:
        return sym(Kq_fin), rows_array([np.eye(nq)[j] for j in rigid_joints], nq)
    S_arr = np.asarray(S, dtype=np.float64)
    S_m = S_arr.reshape(nq, 1) if S_arr.ndim == 1 and S_arr.size == nq else checked_matrix(S_arr, "S")
    if S_m.shape[0] != nq:
        raise InvalidInput(f"S must have {nq} rows (one per joint)", field="S", value=list(S_m.shape))
    nz = S_m.shape[1]
    Kz_m = square_matrix(Kz if Kz is not None else np.full(nz, np.inf), "Kz")
    if Kz_m.shape[0] != nz:
        raise InvalidInput(f"Kz must be {nz} x {nz} (one per synergy)", field="Kz", value=list(Kz_m.shape))
    Kz_fin, rigid_syn = split_infinite(Kz_m, "Kz")
    if transmission == "parallel":
        rows = [np.eye(nq)[j] for j in rigid_joints] + [S_m[:, k] for k in rigid_syn]
        return sym(Kq_fin + S_m @ Kz_fin @ S_m.T), rows_array(rows, nq)
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
    return sym(H), rows_array(rows_s, n)


def contact_space_stiffness(J: ArrayLike, H: ArrayLike, Kc: ArrayLike, P: ArrayLike | None = None) -> FloatArray:
    """Stiffness seen at the contacts, ``(Kc^-1 + (J P) (P^T H P)^-1 (J P)^T)^-1`` (3nc, 3nc) [N/m].

    ``H`` (n, n) is the hand's stiffness (joint space, possibly augmented by synergy coordinates; ``J`` then has
    zero columns for them) and ``P`` (n, r) a basis of the admissible motions (identity by default). Computed as
    ``Kc - Kc Jr (Hr + Jr^T Kc Jr)^+ Jr^T Kc`` with ``Jr = J P``, ``Hr = P^T H P``: valid for a singular ``Hr``
    (joints with no stiffness are free; directions that neither resist nor move a contact are dropped exactly).
    """
    Kc_m = square_matrix(Kc, "Kc")
    if not np.all(np.isfinite(Kc_m)):
        raise InvalidInput("contact stiffness must be finite", field="contact_stiffness")
    if Kc_m.size and np.linalg.eigvalsh(sym(Kc_m)).min() <= 0.0:
        raise InvalidInput("contact stiffness must be positive definite", field="contact_stiffness")
    J_m = checked_matrix(J, "J")
    H_m = square_matrix(H, "H")
    if J_m.shape != (Kc_m.shape[0], H_m.shape[0]):
        raise InvalidInput(
            f"J must be {Kc_m.shape[0]} x {H_m.shape[0]} (3 rows per contact, one column per joint)",
            field="J",
            value=list(J_m.shape),
        )
    P_m = np.eye(H_m.shape[0]) if P is None else checked_matrix(P, "constraints")
    Jr = J_m @ P_m
    Hr = P_m.T @ H_m @ P_m
    if Jr.shape[1] == 0:
        return sym(Kc_m)
    inner = Hr + Jr.T @ Kc_m @ Jr
    raw = sym(Kc_m - Kc_m @ Jr @ psd_pinv(inner) @ Jr.T @ Kc_m)
    # the subtraction cancels where the hand is free: clip its round-off (relative to Kc) to a PSD matrix
    scale = float(np.max(np.abs(np.linalg.eigvalsh(sym(Kc_m))))) if Kc_m.size else 0.0
    return psd_clip(raw, CANCELLATION_RTOL * scale)


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
    """Grasp stiffness ``K`` (6, 6) at the object's centre, linear then angular, symmetric PSD, with its
    intermediate products (:class:`StiffnessTerms`); :func:`grasp_stiffness` returns ``K`` alone.

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
    G_m = checked_matrix(G, "G")
    if G_m.shape[0] != 6:
        raise InvalidInput("G must have 6 rows (linear then angular)", field="G", value=list(G_m.shape))
    J_m = checked_matrix(J, "J")
    H, rows = hand_quadratic(Kq, S, Kz, transmission=transmission)
    nq = J_m.shape[1]
    n = H.shape[0]
    if square_matrix(Kq, "Kq").shape[0] != nq:
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
    K = sym(B @ B.T)  # G Kcs G^T as a Gram matrix: PSD to round-off
    return StiffnessTerms(K=K, contact_space=Kcs, hand=H, basis=P)


Params = ParamSpec("Params")


def _matrix_alone(terms: Callable[Params, StiffnessTerms]) -> Callable[Params, FloatArray]:
    def grasp_stiffness(*args: Params.args, **kwargs: Params.kwargs) -> FloatArray:
        """Grasp stiffness ``K`` (6, 6) at the object's centre, linear then angular, symmetric PSD: the ``K`` of
        :func:`grasp_stiffness_terms`, which takes the same arguments and documents them."""
        return terms(*args, **kwargs).K

    return grasp_stiffness


grasp_stiffness = _matrix_alone(grasp_stiffness_terms)


def principal_stiffness(block: ArrayLike) -> PrincipalStiffness:
    """Eigen-decomposition of a symmetric 3x3 stiffness block: values descending, unit directions as rows."""
    B = square_matrix(block, "K block")
    if B.shape != (3, 3):
        raise InvalidInput("expected a 3x3 block", field="K", value=list(B.shape))
    w, V = np.linalg.eigh(sym(B))
    order = np.argsort(-w, kind="stable")
    dirs = np.array([orient_axes(V[:, k]) for k in order])
    return PrincipalStiffness(values=w[order].copy(), directions=dirs)


def principal_stiffnesses(K: ArrayLike) -> tuple[PrincipalStiffness, PrincipalStiffness]:
    """Principal translational (of ``K[:3, :3]``, [N/m]) and rotational (of ``K[3:, 3:]``, [N·m/rad])
    stiffnesses of a 6x6 grasp stiffness."""
    K_m = square_matrix(K, "K")
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
