"""The grasp-stiffness math (pure numpy): the formula, closed forms, singular pieces, principal stiffnesses."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.errors import InvalidInput
from softsig_service.signatures.matrix_checks import is_psd
from softsig_service.signatures.stiffness import (
    constraint_basis,
    contact_stiffness_matrix,
    grasp_matrix,
    grasp_stiffness,
    grasp_stiffness_terms,
    principal_stiffness,
    principal_stiffnesses,
    skew,
    stiffness_ellipsoid,
)
from softsig_service.signatures.stiffness_types import (
    TRANSMISSIONS,
    BreakForce,
    ContactRecord,
    StiffnessSignature,
    Transmission,
)

SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def _spd(rng: np.random.Generator, n: int, lo: float, hi: float) -> np.ndarray:
    """A random symmetric positive definite matrix with eigenvalues in [lo, hi]."""
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (Q * rng.uniform(lo, hi, size=n)) @ Q.T


def _problem(seed: int) -> dict[str, np.ndarray]:
    """A random well-posed grasp: 1-4 contacts, 1-8 joints, 1-3 synergies (hand-like magnitudes)."""
    rng = np.random.default_rng(seed)
    nc, nq, nz = int(rng.integers(1, 5)), int(rng.integers(1, 9)), int(rng.integers(1, 4))
    pts = rng.normal(scale=0.04, size=(nc, 3))
    return {
        "G": grasp_matrix(pts, rng.normal(scale=0.01, size=3)),
        "J": rng.normal(scale=0.05, size=(3 * nc, nq)),
        "Kq": _spd(rng, nq, 0.05, 2.0),
        "S": rng.normal(size=(nq, nz)),
        "Kz": _spd(rng, nz, 0.1, 5.0),
        "Kc": contact_stiffness_matrix(rng.normal(size=(nc, 3)), rng.uniform(500, 5e4), rng.uniform(0.2, 1.0)),
    }


def _literal(p: dict[str, np.ndarray], *, synergy: bool = True) -> np.ndarray:
    """``G (Kc^-1 + J Kq^-1 J^T + J S Kz^-1 S^T J^T)^-1 G^T`` written out with plain inverses."""
    inv = np.linalg.inv
    C = inv(p["Kc"]) + p["J"] @ inv(p["Kq"]) @ p["J"].T
    if synergy:
        C = C + p["J"] @ p["S"] @ inv(p["Kz"]) @ p["S"].T @ p["J"].T
    return p["G"] @ inv(C) @ p["G"].T


def _close(A: np.ndarray, B: np.ndarray, rtol: float = 1e-8) -> bool:
    return bool(np.allclose(A, B, rtol=0.0, atol=rtol * max(float(np.abs(B).max()), 1e-12)))


# ---------------------------------------------------------------------------------------------------------
# the formula
# ---------------------------------------------------------------------------------------------------------


@settings(max_examples=150, deadline=None)
@given(SEEDS)
def test_series_model_is_the_published_formula(seed: int) -> None:
    p = _problem(seed)
    K = grasp_stiffness(p["G"], p["J"], p["Kq"], p["Kc"], p["S"], p["Kz"], transmission="series")
    assert _close(K, _literal(p))


@settings(max_examples=150, deadline=None)
@given(SEEDS)
def test_parallel_model_adds_the_actuator_beside_the_joint_springs(seed: int) -> None:
    p = _problem(seed)
    K = grasp_stiffness(p["G"], p["J"], p["Kq"], p["Kc"], p["S"], p["Kz"], transmission="parallel")
    Kj = p["Kq"] + p["S"] @ p["Kz"] @ p["S"].T
    expected = p["G"] @ np.linalg.inv(np.linalg.inv(p["Kc"]) + p["J"] @ np.linalg.inv(Kj) @ p["J"].T) @ p["G"].T
    assert _close(K, expected)


@settings(max_examples=150, deadline=None)
@given(SEEDS, st.sampled_from(TRANSMISSIONS))
def test_stiffness_is_symmetric_psd_and_finite(seed: int, transmission: Transmission) -> None:
    p = _problem(seed)
    rng = np.random.default_rng(seed + 1)
    Kq = p["Kq"].copy()
    nq = Kq.shape[0]
    # singular pieces too: a free joint, a force-source synergy, a coupling constraint
    if nq > 1 and rng.random() < 0.5:
        Kq[0, :] = 0.0
        Kq[:, 0] = 0.0
    Kz = np.diag(np.where(rng.random(p["Kz"].shape[0]) < 0.3, 0.0, np.diag(p["Kz"])))
    A = rng.normal(size=(1, nq)) if nq > 2 and rng.random() < 0.5 else None
    K = grasp_stiffness(p["G"], p["J"], Kq, p["Kc"], p["S"], Kz, transmission=transmission, constraints=A)
    assert K.shape == (6, 6)
    assert np.all(np.isfinite(K))
    assert np.array_equal(K, K.T)
    assert is_psd(K)


@settings(max_examples=100, deadline=None)
@given(SEEDS, st.sampled_from(TRANSMISSIONS), st.floats(0.1, 10.0))
def test_stiffer_joints_give_a_stiffer_grasp(seed: int, transmission: Transmission, extra: float) -> None:
    """Loewner order: Kq2 >= Kq1 implies K2 >= K1, hence every eigenvalue is monotone."""
    p = _problem(seed)
    rng = np.random.default_rng(seed + 2)
    nq = p["Kq"].shape[0]
    B = rng.normal(size=(nq, nq))
    Kq2 = p["Kq"] + extra * (B @ B.T) / nq
    args = (p["G"], p["J"])
    K1 = grasp_stiffness(*args, p["Kq"], p["Kc"], p["S"], p["Kz"], transmission=transmission)
    K2 = grasp_stiffness(*args, Kq2, p["Kc"], p["S"], p["Kz"], transmission=transmission)
    scale = float(np.abs(K2).max())
    assert np.linalg.eigvalsh(K2 - K1).min() >= -1e-9 * scale
    assert np.all(np.linalg.eigvalsh(K2) >= np.linalg.eigvalsh(K1) - 1e-9 * scale)


@settings(max_examples=100, deadline=None)
@given(SEEDS)
def test_infinite_actuator_stiffness_removes_the_synergy_term(seed: int) -> None:
    p = _problem(seed)
    nz = p["Kz"].shape[0]
    K_inf = grasp_stiffness(p["G"], p["J"], p["Kq"], p["Kc"], p["S"], np.full(nz, np.inf))
    K_none = grasp_stiffness(p["G"], p["J"], p["Kq"], p["Kc"])
    assert _close(K_inf, K_none)
    assert _close(K_none, _literal(p, synergy=False))


@settings(max_examples=100, deadline=None)
@given(SEEDS)
def test_a_softer_actuator_softens_the_series_grasp(seed: int) -> None:
    p = _problem(seed)
    K_stiff = grasp_stiffness(p["G"], p["J"], p["Kq"], p["Kc"], p["S"], 10.0 * p["Kz"])
    K_soft = grasp_stiffness(p["G"], p["J"], p["Kq"], p["Kc"], p["S"], p["Kz"])
    assert np.linalg.eigvalsh(K_stiff - K_soft).min() >= -1e-9 * float(np.abs(K_stiff).max())


# ---------------------------------------------------------------------------------------------------------
# closed forms
# ---------------------------------------------------------------------------------------------------------


def test_grasp_matrix_maps_contact_forces_to_the_wrench_about_the_centre() -> None:
    rng = np.random.default_rng(3)
    pts, c = rng.normal(size=(3, 3)), rng.normal(size=3)
    f = rng.normal(size=(3, 3))
    w = grasp_matrix(pts, c) @ f.reshape(-1)
    assert np.allclose(w[:3], f.sum(axis=0))
    assert np.allclose(w[3:], sum(np.cross(p - c, fi) for p, fi in zip(pts, f, strict=True)))
    assert np.allclose(skew([1.0, 2.0, 3.0]) @ [4.0, 5.0, 6.0], np.cross([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]))


def test_single_contact_on_a_rigid_hand_gives_g_kc_gt() -> None:
    """One contact at (0, 0, r) above the centre, contact stiffness k, no joint moves it: K = G Kc G^T."""
    k, r = 2000.0, 0.05
    G = grasp_matrix([[0.0, 0.0, r]], [0.0, 0.0, 0.0])
    K = grasp_stiffness(G, np.zeros((3, 1)), [1.0], contact_stiffness_matrix([[0.0, 0.0, -1.0]], k))
    expected = np.zeros((6, 6))
    expected[:3, :3] = k * np.eye(3)
    expected[3, 3] = expected[4, 4] = k * r**2  # rotations about x, y move the point sideways by r * angle
    expected[0, 4] = expected[4, 0] = k * r  # translation along x -> restoring torque about y
    expected[1, 3] = expected[3, 1] = -k * r
    assert np.allclose(K, expected)


def test_two_opposing_fingers_on_slides() -> None:
    """Contacts at (+-a, 0, 0), each on a finger that slides along x with spring kq: along x each contact is
    kc in series with kq, the two in parallel; along y, z only the contacts (the fingers cannot move)."""
    a, kc, kq = 0.03, 4000.0, 1000.0
    G = grasp_matrix([[a, 0.0, 0.0], [-a, 0.0, 0.0]], np.zeros(3))
    J = np.zeros((6, 2))
    J[0, 0] = 1.0  # contact 1 moves along x with finger 1
    J[3, 1] = 1.0  # contact 2 moves along x with finger 2
    Kc = contact_stiffness_matrix([[-1.0, 0, 0], [1.0, 0, 0]], kc)
    K = grasp_stiffness(G, J, [kq, kq], Kc)
    series = kc * kq / (kc + kq)
    assert K[0, 0] == pytest.approx(2.0 * series)
    assert K[1, 1] == pytest.approx(2.0 * kc)
    assert K[2, 2] == pytest.approx(2.0 * kc)
    assert K[3, 3] == pytest.approx(0.0, abs=1e-9)  # rotation about x: the contacts lie on the axis
    assert K[4, 4] == pytest.approx(2.0 * kc * a**2)
    assert K[5, 5] == pytest.approx(2.0 * kc * a**2)
    # a rigid synergy locking q1 + q2: translating the object along x needs dq1 = dq2 (both fingers follow it),
    # which changes q1 + q2, so the hand side becomes rigid and only the contacts remain
    K_locked = grasp_stiffness(G, J, [kq, kq], Kc, [[1.0], [1.0]], [np.inf], transmission="parallel")
    assert K_locked[0, 0] == pytest.approx(2.0 * kc)
    # with zero finger stiffness the object is free along x (the fingers transmit no force)
    K_free = grasp_stiffness(G, J, [0.0, 0.0], Kc)
    assert K_free[0, 0] == pytest.approx(0.0, abs=1e-9)
    assert K_free[1, 1] == pytest.approx(2.0 * kc)


def test_rigid_joint_equals_removing_it_and_coupled_pair_equals_one_joint() -> None:
    rng = np.random.default_rng(7)
    G = grasp_matrix(rng.normal(scale=0.04, size=(2, 3)), np.zeros(3))
    J = rng.normal(scale=0.05, size=(6, 3))
    Kc = contact_stiffness_matrix(rng.normal(size=(2, 3)), 3000.0)
    k = np.array([0.3, 0.5, 0.8])
    K_rigid = grasp_stiffness(G, J, [k[0], np.inf, k[2]], Kc, transmission="parallel")
    K_removed = grasp_stiffness(G, J[:, [0, 2]], k[[0, 2]], Kc)
    assert _close(K_rigid, K_removed)
    # joints 0 and 1 tied 1:1 (a rolling joint): one joint of summed stiffness whose Jacobian column is the sum
    K_coupled = grasp_stiffness(G, J, k, Kc, constraints=[[1.0, -1.0, 0.0]])
    J1 = np.column_stack([J[:, 0] + J[:, 1], J[:, 2]])
    K_one = grasp_stiffness(G, J1, [k[0] + k[1], k[2]], Kc)
    assert _close(K_coupled, K_one)


def test_series_rigid_joint_follows_its_synergy() -> None:
    """A posture servo in the series model: Kq = inf (the joint is its reference), S = 1, Kz = kp. It must give
    the same grasp as the parallel model with a free joint driven by the servo."""
    G = grasp_matrix([[0.03, 0.0, 0.0]], np.zeros(3))
    J = np.zeros((3, 1))
    J[0, 0] = 1.0
    Kc = contact_stiffness_matrix([[-1.0, 0.0, 0.0]], 3000.0)
    K_series = grasp_stiffness(G, J, [np.inf], Kc, [[1.0]], [2000.0], transmission="series")
    K_parallel = grasp_stiffness(G, J, [0.0], Kc, [[1.0]], [2000.0], transmission="parallel")
    assert _close(K_series, K_parallel)
    assert K_series[0, 0] == pytest.approx(3000.0 * 2000.0 / 5000.0)


def test_constraint_basis_and_terms() -> None:
    P = constraint_basis([[1.0, -1.0, 0.0]], 3)
    assert P.shape == (3, 2)
    assert np.allclose(P.T @ P, np.eye(2))
    assert np.allclose(np.array([[1.0, -1.0, 0.0]]) @ P, 0.0)
    assert np.array_equal(constraint_basis(None, 2), np.eye(2))
    p = _problem(11)
    terms = grasp_stiffness_terms(p["G"], p["J"], p["Kq"], p["Kc"], p["S"], p["Kz"], transmission="series")
    nq, nz = p["Kq"].shape[0], p["Kz"].shape[0]
    assert terms.hand.shape == (nq + nz, nq + nz)  # series: joints and synergy coordinates
    assert np.allclose(terms.K, p["G"] @ terms.contact_space @ p["G"].T)


# ---------------------------------------------------------------------------------------------------------
# principal stiffnesses
# ---------------------------------------------------------------------------------------------------------


@settings(max_examples=100, deadline=None)
@given(SEEDS)
def test_principal_stiffnesses_diagonalise_the_blocks(seed: int) -> None:
    p = _problem(seed)
    K = grasp_stiffness(p["G"], p["J"], p["Kq"], p["Kc"], p["S"], p["Kz"])
    for ps, block in zip(principal_stiffnesses(K), (K[:3, :3], K[3:, 3:]), strict=True):
        R = ps.directions
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-9)
        assert np.all(np.diff(ps.values) <= 1e-9 * max(1.0, float(ps.values[0])))
        assert np.allclose(R.T @ np.diag(ps.values) @ R, block, atol=1e-9 * max(1.0, float(np.abs(block).max())))
        for r in R:  # sign rule: the largest component is positive
            assert r[int(np.argmax(np.abs(r)))] > 0.0


def test_principal_stiffness_of_a_diagonal_block_and_ellipsoid() -> None:
    ps = principal_stiffness(np.diag([100.0, 300.0, 200.0]))
    assert np.allclose(ps.values, [300.0, 200.0, 100.0])
    assert np.allclose(np.abs(ps.directions), np.eye(3)[[1, 2, 0]])
    axes, _ = stiffness_ellipsoid(np.diag([100.0, 0.0, 50.0]))
    assert np.allclose(axes[:2], [0.01, 0.02])
    assert np.isinf(axes[2])


# ---------------------------------------------------------------------------------------------------------
# bad input and the result type
# ---------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"Kq": [-1.0, 1.0]}, "Kq"),
        ({"Kq": [np.nan, 1.0]}, "Kq"),
        ({"Kq": [[1.0, 0.5], [0.0, 1.0]]}, "Kq"),
        ({"J": np.zeros((4, 2))}, "J"),
        ({"J": np.zeros((3, 3))}, "Kq"),
        ({"Kc": np.zeros((3, 3))}, "contact_stiffness"),
        ({"Kc": np.full(3, np.inf)}, "contact_stiffness"),
        ({"transmission": "belt"}, "transmission"),
        ({"S": np.ones((3, 1))}, "S"),
        ({"S": np.ones((2, 1)), "Kz": [1.0, 1.0]}, "Kz"),
        ({"constraints": np.ones((1, 3))}, "constraints"),
    ],
)
def test_bad_input_names_the_field(kwargs: dict[str, object], field: str) -> None:
    args: dict[str, object] = {
        "G": grasp_matrix([[0.0, 0.0, 0.05]], np.zeros(3)),
        "J": np.ones((3, 2)),
        "Kq": [1.0, 1.0],
        "Kc": np.eye(3) * 1000.0,
    }
    args.update(kwargs)
    with pytest.raises(InvalidInput) as err:
        grasp_stiffness(**args)  # type: ignore[arg-type]
    assert err.value.field == field
    if field == "transmission":
        assert err.value.choices == ["parallel", "series"]


def test_contact_stiffness_matrix_bad_values() -> None:
    with pytest.raises(InvalidInput) as err:
        contact_stiffness_matrix([[0.0, 0.0, 1.0]], -5.0)
    assert err.value.field == "contact_stiffness"
    with pytest.raises(InvalidInput) as err:
        contact_stiffness_matrix([[0.0, 0.0, 0.0]], 5.0)
    assert err.value.field == "contacts.normal[0]"
    Kc = contact_stiffness_matrix([[0.0, 0.0, 2.0]], 1000.0, 0.25)
    assert np.allclose(Kc, np.diag([250.0, 250.0, 1000.0]))


def test_signature_json_has_exactly_the_documented_keys() -> None:
    K = np.diag([3.0, 2.0, 1.0, 0.3, 0.2, 0.1])
    pt, pr = principal_stiffnesses(K)
    ss = StiffnessSignature(
        K=K,
        principal_translational=pt,
        principal_rotational=pr,
        break_forces=(BreakForce(np.array([1.0, 0, 0]), 12.5, False, "displacement", 0.021, 0.4),),
        object={"kind": "sphere", "radius": 0.04},
        closure_command={"actuators": ["a"], "values": [1.0]},
        parameters={"contact_stiffness": 3000.0},
        contacts=(ContactRecord(np.zeros(3), np.array([0, 0, 1.0]), np.array([0, 0, 2.0]), "b", "g"),),
        hand="h",
    )
    d = json.loads(json.dumps(ss.to_json_dict()))
    assert set(d) == {
        "K",
        "principal_translational",
        "principal_rotational",
        "break_forces",
        "object",
        "frame_id",
        "parameters",
        "contacts",
    }
    assert d["frame_id"] == "hand"
    assert np.allclose(d["K"], K)
    assert set(d["principal_translational"]) == {"values", "directions"}
    assert d["principal_translational"]["values"] == [3.0, 2.0, 1.0]
    assert d["break_forces"][0]["force"] == 12.5 and d["break_forces"][0]["direction"] == [1.0, 0.0, 0.0]
    assert d["parameters"]["closure_command"] == {"actuators": ["a"], "values": [1.0]}
    assert d["contacts"][0]["normal_force"] == 2.0
