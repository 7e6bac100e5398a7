"""The matrices of a simulated grasp's stiffness (docs/design.md §5).

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

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.signatures.stiffness import contact_stiffness_matrix, grasp_matrix, grasp_stiffness_terms
from softsig_service.signatures.stiffness_types import (
    DEFAULT_CONTACT_STIFFNESS,
    ContactRecord,
    StiffnessTerms,
    Transmission,
)
from softsig_service.simulation.grasp_contacts import contact_forces
from softsig_service.simulation.grasp_state import (
    DEFAULT_TRANSMISSION,
    Grasp,
)

FloatArray = NDArray[np.float64]


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


def hand_object_contacts(grasp: Grasp, data: mujoco.MjData | None = None) -> list[tuple[int, ContactRecord]]:
    """The loaded hand-object contacts of ``data`` (default: the grasp): (contact index, record), hand frame."""
    d = grasp.data if data is None else data
    model = grasp.model
    R = grasp.hand_rotation(d)
    out: list[tuple[int, ContactRecord]] = []
    for i, other, f_world, normal in contact_forces(model, d, grasp.object_geom, grasp.object_body):
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
