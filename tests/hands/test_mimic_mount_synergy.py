"""Mimic couplings in MuJoCo, the manifest's mount pose, and the synergy closure in both realisations."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from mini_hand import mini_hand

from softsig_service.config import Settings
from softsig_service.errors import FrameNotFound, InvalidHandModel, InvalidManifest
from softsig_service.geometry.transforms import rpy_to_matrix
from softsig_service.hands.closure import prepare_data, run_closure, simulate_closure
from softsig_service.hands.manifest import load_manifest
from softsig_service.hands.mimic import mimic_couplings
from softsig_service.hands.model import HandModel, compile_hand, load_hand
from softsig_service.hands.summary import hand_info
from softsig_service.hands.synergy import synergy_targets

# the description's mimic tags, resolved to the synergy joint (f*_dist mimic f*_prox: a chain)
RESOLVED = {
    "f1_prox": (0.4, 0.0), "f1_dist": (0.3, 0.0), "f2_prox": (0.3, 0.0), "f2_dist": (0.225, 0.0),
    "thumb_prox": (0.3, 0.1), "thumb_dist": (0.15, 0.05),
}  # fmt: skip

POSTURE = """
kind = "posture"
open = { synergy_joint = 0.0 }
closed = { synergy_joint = 0.8 }  # f1_prox = 0.4 s stays below its 0.35 rad limit
kp = 5.0
kv = 0.05
"""


def _joint_history(hand: HandModel) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Times [s] and every named joint's position [rad] through the manifest's closure (gravity off)."""
    model = copy.copy(hand.model)
    model.opt.gravity[:] = 0.0
    data = prepare_data(hand, model)
    names = [model.joint(j).name for j in range(model.njnt)]
    times, rows = [0.0], [data.qpos[model.jnt_qposadr].copy()]

    def record() -> None:
        times.append(float(data.time))
        rows.append(data.qpos[model.jnt_qposadr].copy())

    closure = hand.manifest.closure
    run_closure(hand, model, data, duration=closure.duration, settle=closure.settle, every=5, on_sample=record)
    q = np.array(rows)
    return np.array(times), {n: q[:, k] for k, n in enumerate(names)}


def test_mimic_chains_resolve_to_the_root() -> None:
    hand = load_hand(str(Path(__file__).parent / "data" / "mini_hand" / "hand.toml"), Settings())
    got = {c.joint: (c.root, round(c.multiplier, 12), round(c.offset, 12)) for c in hand.mimics}
    assert got == {j: ("synergy_joint", m, o) for j, (m, o) in RESOLVED.items()}
    with pytest.raises(InvalidHandModel, match="cycle"):
        mimic_couplings(
            '<robot><joint name="a"><mimic joint="b"/></joint><joint name="b"><mimic joint="a"/></joint></robot>'
        )
    with pytest.raises(FrameNotFound) as info:
        mimic_couplings('<robot><joint name="a"><mimic joint="nope"/></joint></robot>')
    assert info.value.choices == ["a"]


def test_mimic_coupling_holds_during_a_closure(tmp_path: Path) -> None:
    # only the synergy joint is servoed: the six finger joints move through the mimic equalities alone
    hand = load_hand(str(mini_hand(tmp_path, POSTURE)), Settings())
    assert hand.model.neq == 6 and hand.model.nu == 1
    _, q = _joint_history(hand)
    s = q["synergy_joint"]
    assert s[-1] == pytest.approx(0.8, abs=0.01)
    for joint, (m, o) in RESOLVED.items():
        err = np.abs(q[joint] - (m * s + o))
        assert err.max() < 1e-3, (joint, float(err.max()))


def _tip_points(hand: HandModel) -> np.ndarray:
    return simulate_closure(hand, duration=0.01, settle=0.0, surface_points=0).positions[0]


def test_mount_pose_turns_the_description_into_the_hand_frame(tmp_path: Path) -> None:
    posed = load_hand(str(mini_hand(tmp_path / "a")), Settings())
    bare = load_hand(str(mini_hand(tmp_path / "b", mount_pose="")), Settings())
    info = hand_info(posed)["hand_frame"]
    # stated: rpy (pi/2, 0, pi/2) puts hand +x along base +y and hand +z (the approach) along base +x
    assert info["relative_to"] == "base_link"
    np.testing.assert_allclose(info["x"], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(info["y"], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(info["z"], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(hand_info(bare)["hand_frame"]["z"], [0, 0, 1])
    R = rpy_to_matrix(math.pi / 2, 0.0, math.pi / 2)
    p_bare, p_posed = _tip_points(bare), _tip_points(posed)
    np.testing.assert_allclose(p_posed, p_bare @ R, atol=1e-9)  # every point re-expressed: p_H = R^T p_M
    assert np.all(p_posed[:3, 2] > 0.12)  # fingertips out along the approach, +z
    # the same pose as a quaternion (x, y, z, w) and with an origin: the points shift by -xyz along the axes
    quat = "{ xyz = [0.01, 0.0, 0.0], quaternion = { x = 0.5, y = 0.5, z = 0.5, w = 0.5 } }"
    shifted = load_hand(str(mini_hand(tmp_path / "c", mount_pose=quat)), Settings())
    np.testing.assert_allclose(_tip_points(shifted), p_posed - [0.0, 0.0, 0.01], atol=1e-9)
    # mass and inertia are the description's: the mount pose moves frames, not matter
    assert shifted.model.body_mass.sum() == pytest.approx(bare.model.body_mass.sum())


@pytest.mark.parametrize(
    ("pose", "field"),
    [
        ("{ rpy = [0.0, 0.0, 0.0], quaternion = { x = 0.0, y = 0.0, z = 0.0, w = 1.0 } }", "mount_pose"),
        ("{ quaternion = { x = 0.0, y = 0.0, z = 0.0, w = 0.0 } }", "mount_pose"),
        ("{ xyz = [0.0, 0.0] }", "mount_pose.xyz[2]"),
        ("{ rpy = [0.0, 0.0, 0.0], scale = 2.0 }", "mount_pose.scale"),
    ],
)
def test_bad_mount_pose_names_the_field(tmp_path: Path, pose: str, field: str) -> None:
    with pytest.raises(InvalidManifest) as info:
        load_manifest(mini_hand(tmp_path, mount_pose=pose))
    assert info.value.field == field


def _synergy(realisation: str, extra: str = "") -> str:
    return (
        f'kind = "synergy"\nsynergy_joint = "synergy_joint"\nrealisation = "{realisation}"\nstiffness = 0.05\n{extra}'
    )


def test_kinematic_synergy_follows_multiplier_times_s(tmp_path: Path) -> None:
    hand = load_hand(str(mini_hand(tmp_path, _synergy("kinematic"))), Settings())
    assert hand.model.neq == 0 and hand.model.nu == 7  # a servo per coupled joint, the mimics replaced
    times, q = _joint_history(hand)
    worst = 0.0
    for k, t in enumerate(times):
        s = min(t / hand.manifest.closure.duration, 1.0)
        for joint, target in synergy_targets(hand.synergy, hand.model, s).items():
            worst = max(worst, abs(q[joint][k] - target))
    assert math.degrees(worst) < 2.0
    # f1_prox = 0.4 s reaches its 0.35 rad limit at s = 0.875 and stays clipped there
    assert q["f1_prox"][-1] == pytest.approx(0.35, abs=math.radians(0.5))


def _obstacle(spec: mujoco.MjSpec) -> None:
    """A fixed block in front of finger f1's tip (hand frame: f1 at x = -0.02 closes toward -y)."""
    geom = spec.worldbody.add_geom(name="block", type=mujoco.mjtGeom.mjGEOM_BOX)
    geom.size = [0.008, 0.003, 0.012]
    geom.pos = [-0.02, 0.012, 0.115]


def test_adaptive_synergy_free_closure_and_a_blocked_finger(tmp_path: Path) -> None:
    toml = mini_hand(tmp_path, _synergy("adaptive"))
    free = load_hand(str(toml), Settings())
    assert free.model.ntendon == 1 and free.model.nu == 1 and free.model.neq == 0
    _, q_free = _joint_history(free)
    for joint, target in synergy_targets(free.synergy, free.model, 1.0).items():
        assert q_free[joint][-1] == pytest.approx(target, abs=math.radians(1.0)), joint
    blocked = compile_hand(load_manifest(toml), toml.parent, Settings().limits, edit=_obstacle)
    _, q_blocked = _joint_history(blocked)
    assert q_blocked["f1_dist"][-1] < q_free["f1_dist"][-1] - 0.1  # the block stops f1 early
    for joint in ("f2_prox", "f2_dist", "thumb_prox", "thumb_dist"):  # the others close as in free space
        assert q_blocked[joint][-1] == pytest.approx(q_free[joint][-1], abs=math.radians(0.5)), joint


def test_synergy_from_manifest_multipliers_and_bad_joints(tmp_path: Path) -> None:
    extra = "multipliers = { f1_prox = 1.0, f2_prox = 0.5 }\noffsets = { f2_prox = 0.2 }\n"
    closure = 'kind = "synergy"\nrealisation = "kinematic"\n' + extra
    hand = load_hand(str(mini_hand(tmp_path / "a", closure)), Settings())
    assert [(c.joint, c.multiplier, c.offset) for c in hand.synergy] == [("f1_prox", 1.0, 0.0), ("f2_prox", 0.5, 0.2)]
    # the joints the synergy drives lose their mimic equality; the distal ones keep theirs
    assert hand.model.neq == 4
    bad = closure.replace("f2_prox = 0.5", "f9_prox = 0.5").replace("offsets = { f2_prox = 0.2 }\n", "")
    with pytest.raises(FrameNotFound) as info:
        load_hand(str(mini_hand(tmp_path / "b", bad)), Settings())
    assert info.value.field == "closure.multipliers.f9_prox"
    with pytest.raises(InvalidHandModel) as info2:
        load_hand(str(mini_hand(tmp_path / "c", _synergy("adaptive").replace("synergy_joint\"\n", "f1_dist\"\n", 1))),
                  Settings())  # fmt: skip
    assert info2.value.field == "closure.synergy_joint"
    with pytest.raises(InvalidManifest) as info3:
        load_manifest(mini_hand(tmp_path / "d", _synergy("adaptive", extra)))
    assert info3.value.field == "closure" and "exactly one" in str(info3.value)


def test_mount_pose_of_an_mjcf_hand(tmp_path: Path) -> None:
    import shutil

    folder = tmp_path / "sdm"
    shutil.copytree(Settings().hands_dir / "sdm_hand", folder)
    toml = folder / "hand.toml"
    toml.write_text(
        toml.read_text().replace(
            'mount = "mount"\n',
            'mount = "mount"\nmount_pose = { xyz = [0.0, 0.0, 0.01], rpy = [0.0, 0.0, 1.5707963267948966] }\n',
        )
    )
    posed = load_hand(str(toml), Settings())
    bare = load_hand("sdm_hand", Settings())
    R = rpy_to_matrix(0.0, 0.0, math.pi / 2)
    # sites (the fingertips and the wrist) follow the frame: p_H = R^T (p_M - xyz)
    np.testing.assert_allclose(_tip_points(posed), (_tip_points(bare) - [0.0, 0.0, 0.01]) @ R, atol=1e-9)
    closed_posed = simulate_closure(posed, surface_points=0).positions[-1]
    closed_bare = simulate_closure(bare, surface_points=0).positions[-1]  # gravity off: the closure is the same
    np.testing.assert_allclose(closed_posed, (closed_bare - [0.0, 0.0, 0.01]) @ R, atol=1e-6)
