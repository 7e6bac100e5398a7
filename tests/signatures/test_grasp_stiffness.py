"""Stiffness signatures of the built-in hands in MuJoCo: grasp, matrices, K, pull test, plot."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from softsig_service.errors import InvalidInput
from softsig_service.experiments.stiffness_plot import plot_stiffness_signature
from softsig_service.hands.closure import prepare_data
from softsig_service.hands.model import builtin_hand_names, load_hand
from softsig_service.signatures.matrix_checks import is_psd
from softsig_service.signatures.stiffness_types import StiffnessSignature
from softsig_service.simulation.grasp import grasp_object
from softsig_service.simulation.grasp_matrices import actuator_synergies, grasp_matrices, hand_object_contacts
from softsig_service.simulation.grasp_state import Grasp
from softsig_service.simulation.pullout import (
    AXIS_DIRECTIONS,
    SPHERE_DIRECTIONS,
    PullSettings,
    default_directions,
    pull_test,
    pull_tests,
)
from softsig_service.simulation.stiffness_signature import compute_stiffness_signature

HANDS = builtin_hand_names()
# reduced direction set for the tests: +x, +y, +z (the default is 26)
TEST_DIRECTIONS = AXIS_DIRECTIONS[[0, 2, 4]]


@pytest.fixture(scope="module")
def apple_signatures() -> dict[str, StiffnessSignature]:
    return {h: compute_stiffness_signature(load_hand(h), "apple", directions=TEST_DIRECTIONS) for h in HANDS}


@pytest.fixture(scope="module")
def gripper_box() -> Grasp:
    return grasp_object(load_hand("parallel_gripper"), "box")


def test_the_four_hands_are_built_in() -> None:
    assert {"pisa_iit_softhand", "sdm_hand", "rbo_hand2", "parallel_gripper"} <= set(HANDS)


@pytest.mark.parametrize("hand", HANDS)
def test_apple_stiffness_is_finite_symmetric_psd(apple_signatures: dict[str, StiffnessSignature], hand: str) -> None:
    ss = apple_signatures[hand]
    K = ss.K
    assert K.shape == (6, 6)
    assert np.all(np.isfinite(K))
    assert np.array_equal(K, K.T)
    assert is_psd(K)
    assert np.all(ss.principal_translational.values >= -1e-9 * ss.principal_translational.values[0])
    assert ss.principal_translational.values[0] > 0.0
    assert ss.frame_id == "hand"
    assert ss.contacts, "a grasp has contacts"


@pytest.mark.parametrize("hand", HANDS)
def test_apple_break_forces(apple_signatures: dict[str, StiffnessSignature], hand: str) -> None:
    ss = apple_signatures[hand]
    assert len(ss.break_forces) == len(TEST_DIRECTIONS)
    cap = ss.parameters["pull"]["cap"]
    for b, d in zip(ss.break_forces, TEST_DIRECTIONS, strict=True):
        assert np.allclose(b.direction, d)
        assert np.isfinite(b.force)
        assert 0.0 <= b.force <= cap
        assert b.force > 0.0
        assert b.reason in ("displacement", "contact_lost", "cap")
        assert b.capped == (b.reason == "cap")
        if not b.capped:
            assert b.displacement > ss.parameters["pull"]["displacement_threshold"] or b.reason == "contact_lost"


def test_every_hand_finds_a_power_grasp_of_the_apple(apple_signatures: dict[str, StiffnessSignature]) -> None:
    """The automatic placement, or a nearby one of the power-grasp search, is held by every built-in hand."""
    assert {h for h, ss in apple_signatures.items() if ss.parameters["grasp"]["held"]} == set(HANDS)


def test_the_softhands_stiffness_is_the_same_on_either_mount(apple_signatures: dict[str, StiffnessSignature]) -> None:
    """The SoftHand in line and on its bracket is one hand on two flanges (the same hand in its grasp frame): its
    translational stiffness, rotated into the grasp frame, matches the bracket's (placement discretised in 1 mm
    steps along another axis, hence a tolerance)."""
    Ks = {}
    for name in ("pisa_iit_softhand", "pisa_iit_softhand_bracket"):
        R = load_hand(name).grasp_frame[:3, :3]
        Ks[name] = R.T @ apple_signatures[name].K[:3, :3] @ R
    a, b = Ks["pisa_iit_softhand_bracket"], Ks["pisa_iit_softhand"]
    assert np.linalg.norm(a - b) <= 0.15 * np.linalg.norm(a)
    assert np.allclose(np.linalg.eigvalsh(a), np.linalg.eigvalsh(b), rtol=0.15)


@pytest.mark.parametrize("hand", ["pisa_iit_softhand", "rbo_hand2", "sdm_hand", "parallel_gripper"])
def test_every_hand_holds_the_box_with_positive_break_forces(hand: str) -> None:
    ss = compute_stiffness_signature(load_hand(hand), "box", directions=TEST_DIRECTIONS)
    assert ss.parameters["grasp"]["held"]
    assert all(np.isfinite(b.force) and b.force > 0.0 for b in ss.break_forces)
    assert is_psd(ss.K)


def test_break_forces_are_repeatable() -> None:
    """Two independent grasps and pulls give the same numbers (deterministic simulation)."""
    hand = load_hand("sdm_hand")
    runs = [compute_stiffness_signature(hand, "apple", directions=TEST_DIRECTIONS[:2]).to_json_dict() for _ in range(2)]
    assert runs[0] == runs[1]
    assert runs[0]["parameters"]["grasp"]["held"], "the SDM hand cages the apple"
    assert all(b["force"] > 0.0 for b in runs[0]["break_forces"])


def test_gripper_resists_a_push_along_its_closing_axis_more_than_a_pull_along_its_fingers(
    gripper_box: Grasp,
) -> None:
    """The known order for a parallel-jaw grasp: across the jaws the object is blocked by the jaw itself (here up
    to the jaw's force limit), along the fingers only friction holds it."""
    assert gripper_box.held
    closing = [pull_test(gripper_box, [0.0, s, 0.0]) for s in (1.0, -1.0)]
    along_fingers = pull_test(gripper_box, [0.0, 0.0, 1.0])
    assert not along_fingers.capped
    for push in closing:
        assert push.force > 1.5 * along_fingers.force
    # friction bound: pulling along the fingers cannot beat mu * (total normal force) of the grasp
    total_normal = sum(c.normal_force for _, c in hand_object_contacts(gripper_box))
    assert along_fingers.force <= gripper_box.object.friction * total_normal * 1.05


def test_gripper_matrices(gripper_box: Grasp) -> None:
    m = grasp_matrices(gripper_box)
    assert m.dof_names == ("left_jaw", "right_jaw")
    assert np.allclose(np.diag(m.Kz), [2000.0, 2000.0])  # posture servos: kp, S = identity on their joints
    assert np.allclose(m.S, np.eye(2))
    assert m.constraints.shape == (1, 2)  # the jaws are tied 1:1
    for k, c in enumerate(m.contacts):
        J = m.J[3 * k : 3 * k + 3]
        left = c.hand_body == "left_jaw"
        assert np.allclose(J[:, 0 if left else 1], [0.0, 1.0 if left else -1.0, 0.0])
        assert c.normal[1] == pytest.approx(-1.0 if left else 1.0, abs=1e-6)  # from the jaw into the object
        assert c.force[1] * c.normal[1] > 0.0  # the jaw pushes the object
        assert np.allclose(J[:, 1 if left else 0], 0.0)
    # a settled grasp is in equilibrium: the contact forces' net wrench about the centre is ~0
    f = np.concatenate([c.force for c in m.contacts])
    w = m.G @ f
    total = sum(float(np.linalg.norm(c.force)) for c in m.contacts)
    assert np.linalg.norm(w[:3]) < 0.02 * total
    assert np.all(np.array([c.normal_force for c in m.contacts]) > 0.0)


def test_softhand_synergy_and_rolling_joints() -> None:
    """S is the tendon's coefficients, Kz = kp * gear^2 while the motor is not saturated, and every rolling joint
    (hinge pair tied 1:1) gives one constraint row."""
    hand = load_hand("pisa_iit_softhand")
    model = hand.model
    data = prepare_data(hand, model)
    dofs = np.arange(model.nv)
    syn = actuator_synergies(model, data, dofs)
    assert syn.names == ("synergy",)
    assert not syn.saturated
    coef = {model.joint(int(model.dof_jntid[d])).name: syn.S[d, 0] for d in dofs}
    assert coef["thumb_abd"] == pytest.approx(1.3)
    assert coef["index_abd"] == pytest.approx(-0.2)
    assert coef["index_prox_1"] == pytest.approx(1.0)
    assert syn.Kz[0, 0] == pytest.approx(hand.manifest.physical.actuator_stiffness, rel=2e-3)
    grasp = grasp_object(hand, "apple")
    m = grasp_matrices(grasp)
    assert m.constraints.shape == (14, 33)
    for row in m.constraints:
        nz = np.flatnonzero(np.abs(row) > 1e-9)
        assert len(nz) == 2
        assert sorted(np.round(row[nz], 6)) == [-1.0, 1.0]
    assert m.S.shape == (33, 1)
    assert m.Kz.shape == (1, 1)


def test_default_directions() -> None:
    D = default_directions()
    assert D.shape == (26, 3)
    assert np.allclose(np.linalg.norm(D, axis=1), 1.0)
    assert len({tuple(np.round(d, 9)) for d in D}) == 26
    assert np.allclose(D[:6], AXIS_DIRECTIONS)
    assert np.allclose(SPHERE_DIRECTIONS, D)


def test_bad_input(gripper_box: Grasp) -> None:
    hand = load_hand("parallel_gripper")
    with pytest.raises(InvalidInput) as err:
        grasp_object(hand, "apple", center=[0.0, 0.0, 0.05])  # inside the housing
    assert err.value.field == "center"
    with pytest.raises(InvalidInput) as err:
        grasp_object(hand, "apple", center=[0.0, np.nan, 0.1])
    assert err.value.field == "center"
    with pytest.raises(InvalidInput) as err:
        grasp_object(hand, "pear")
    assert err.value.field == "object.name"
    with pytest.raises(InvalidInput) as err:
        pull_test(gripper_box, [0.0, 0.0, 0.0])
    assert err.value.field == "directions[0]"
    with pytest.raises(InvalidInput) as err:
        PullSettings(mode="yank")  # type: ignore[arg-type]
    assert err.value.field == "pull.mode"
    with pytest.raises(InvalidInput) as err:
        compute_stiffness_signature(hand, "box", transmission="belt", pull=False)  # type: ignore[arg-type]
    assert err.value.field == "transmission"


def test_ramp_mode_and_pull_tests(gripper_box: Grasp) -> None:
    ramp = pull_test(gripper_box, [0.0, 0.0, 1.0], PullSettings(mode="ramp", rate=100.0))
    assert ramp.reason == "displacement" and 0.0 < ramp.force < 200.0
    both = pull_tests(gripper_box, [[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]])
    assert both[0].force == both[1].force  # directions are normalised


def test_signature_json_and_plot(apple_signatures: dict[str, StiffnessSignature], tmp_path: Path) -> None:
    ss = apple_signatures["parallel_gripper"]
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
    assert d["object"]["kind"] == "ellipsoid" and d["object"]["mass"] == pytest.approx(0.18)
    assert d["parameters"]["closure_command"]["kind"] == "posture"
    assert d["parameters"]["transmission"] == "parallel"
    out = plot_stiffness_signature(ss, tmp_path / "ss.png")
    assert out.stat().st_size > 10_000
    with pytest.raises(InvalidInput):
        plot_stiffness_signature(ss, tmp_path / "ss.txt")


def test_the_break_force_scale_ignores_one_outlier_and_keeps_a_spread() -> None:
    from softsig_service.experiments.stiffness_plot import robust_limit

    spread = np.array([4.0, 5.0, 6.0, 5.5, 4.5, 7.0, 6.5, 5.0])
    assert robust_limit(spread) == 7.0  # no outlier: the largest force
    assert robust_limit(np.append(spread, 100.0)) == 7.0  # one 100 N outlier is left off the scale
    assert robust_limit(np.array([1.0, 100.0])) == 100.0  # too few forces to call one an outlier
