"""The official Pisa/IIT SoftHand description as a user hand, and the self-collision pairs left unchecked.

The description (``data/pisa_iit_soft_hand_official``, vendored unedited) has 33 mimic tags on its synergy joint
and collision meshes of neighbouring links that overlap; checked, those pairs spread the fingers when the synergy
closes them. The closure is compared with the description's own kinematics, computed here from the expanded URDF.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest

from softsig_service.config import Settings
from softsig_service.hands.closure import (
    prepare_data,
    reference_points_world,
    run_closure,
    simulate_closure,
    to_hand_frame,
)
from softsig_service.hands.model import HandModel, compile_hand, load_hand
from softsig_service.hands.self_collision import srdf_disabled_pairs, urdf_adjacent_pairs
from softsig_service.hands.summary import hand_info
from softsig_service.signatures.closure import ellipsoid_closure_signature

FOLDER = Path(__file__).resolve().parent / "data" / "pisa_iit_soft_hand_official"
SYNERGY = "soft_hand_synergy_joint"
TIP_OFFSET = np.array([0.02, 0.0, 0.0])  # the manifest's fingertip offset in each distal link [m]
FINGERS = ("thumb", "index", "middle", "ring", "little")

# git blob ids of the upstream files (CentroEPiaggio/pisa-iit-soft-hand at 174eebc): the copies are unedited
UPSTREAM_BLOBS = {
    "LICENSE": "fadb955cdc966b240df9ff30013ced536e748b1e",
    "soft_hand_description/README.md": "c3e476bf13d4560e67c0735d5e6ca58f1b7eb5a5",
    "soft_hand_description/package.xml": "2e5c83fd9864cab565d295f61a7366dce63bdd19",
    "soft_hand_description/meshes/LICENSE": "9d1b625b61f89d22b20f40f4deac4e6c7097c506",
    "soft_hand_description/meshes/fingertip_collision.stl": "c5f054cd3cb0d0f47d0e60ace376d2934d9d69fb",
    "soft_hand_description/meshes/knuckle_collision.stl": "51b1ae01b77d3673d268f6b9e2c7998fc14eaa9c",
    "soft_hand_description/meshes/palm_right_collision.stl": "43a64886036a3cfa4ecc1c81b831414b39de23a8",
    "soft_hand_description/meshes/phalanx_collision.stl": "43db9375fd841a67a73b1d2153fdfd7db35852f1",
    "soft_hand_description/meshes/thumb_knuckle_right_collision.stl": "ebf29150d567b8302c71143a933559fc9eb601e9",
    "soft_hand_description/model/accesories/clamp.urdf.xacro": "3132fe3744a2bb8279a630ab285eb4fa889c5cff",
    "soft_hand_description/model/accesories/kuka_coupler.urdf.xacro": "7d5185755060b8ead38e1d049babd9ff02dd3c96",
    "soft_hand_description/model/accesories/softhand_base.urdf.xacro": "3181e21cc4b83287a3a95396bc81112013337fae",
    "soft_hand_description/model/materials.urdf.xacro": "60c0697d224cb4b696ad93c312c2a07c58f238ef",
    "soft_hand_description/model/soft_hand.gazebo.xacro": "159e20fd8d353b4f770f2d056d3d26150cb6e84e",
    "soft_hand_description/model/soft_hand.inertia.xacro": "56be4c2c2dd7a692be314ee9aa74e363e07c6e72",
    "soft_hand_description/model/soft_hand.transmission.xacro": "8e53f7b4c4d32e14e08cef6be35f40d744b24ece",
    "soft_hand_description/model/soft_hand.urdf.xacro": "45270c354188367ca5a73c658e3ac72fd1d55aaf",
}


def _git_blob(path: Path) -> str:
    data = path.read_bytes()
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


@pytest.fixture(scope="module")
def adaptive() -> HandModel:
    return load_hand(str(FOLDER / "hand.toml"), Settings())


@pytest.fixture(scope="module")
def kinematic(adaptive: HandModel) -> HandModel:
    closure = adaptive.manifest.closure.model_copy(update={"realisation": "kinematic"})
    manifest = adaptive.manifest.model_copy(update={"closure": closure})
    return compile_hand(manifest, FOLDER, Settings().limits, excluded=adaptive.excluded)


def spread(points: np.ndarray) -> float:
    """Mean distance [m] of the five fingertip points (the first five reference points) to their centroid."""
    tips = points[:5]
    return float(np.linalg.norm(tips - tips.mean(axis=0), axis=1).mean())


# --- the description's kinematics, independent of softsig and MuJoCo ------------------------------------------


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    """URDF rpy: R = Rz(y) Ry(p) Rx(r)."""
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _axis_angle(axis: np.ndarray, q: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(q) * K + (1 - math.cos(q)) * K @ K


def _floats(text: str | None, default: str = "0 0 0") -> np.ndarray:
    return np.array([float(x) for x in (text or default).split()])


def fk_joint_values(urdf: ET.Element, s: float) -> dict[str, float]:
    """Every mimic joint at ``multiplier * s`` clipped to its limits, the synergy joint at s (direct mimics)."""
    q = {SYNERGY: s}
    for joint in urdf.findall("joint"):
        mimic = joint.find("mimic")
        if mimic is None:
            continue
        assert mimic.get("joint") == SYNERGY and mimic.get("offset") is None
        limit = joint.find("limit")
        assert limit is not None
        lo, hi = float(limit.get("lower", "0")), float(limit.get("upper", "0"))
        q[joint.get("name", "")] = min(max(float(mimic.get("multiplier", "1")) * s, lo), hi)
    return q


def fk_points(urdf: ET.Element, s: float) -> np.ndarray:
    """The reference points (five fingertips, then the wrist) in the hand frame at synergy ``s``."""
    by_child = {j.find("child").get("link"): j for j in urdf.findall("joint")}  # type: ignore[union-attr]
    q = fk_joint_values(urdf, s)

    def pose(link: str) -> np.ndarray:
        joint = by_child.get(link)
        if joint is None:
            return np.eye(4)
        parent = joint.find("parent").get("link")  # type: ignore[union-attr]
        origin = joint.find("origin")
        T = np.eye(4)
        if origin is not None:
            T[:3, :3] = _rpy(*_floats(origin.get("rpy")))
            T[:3, 3] = _floats(origin.get("xyz"))
        if joint.get("type") in ("revolute", "continuous"):
            axis = joint.find("axis")
            M = np.eye(4)
            M[:3, :3] = _axis_angle(_floats(axis.get("xyz") if axis is not None else None, "1 0 0"),
                                    q.get(joint.get("name", ""), 0.0))  # fmt: skip
            T = T @ M
        return pose(str(parent)) @ T

    tips = [pose(f"soft_hand_{f}_distal_link") @ np.append(TIP_OFFSET, 1.0) for f in FINGERS]
    points_flange = np.array([t[:3] for t in tips] + [pose("flange")[:3, 3]])
    R_MH = _rpy(math.pi / 2, 0.0, math.pi / 2)  # the manifest's mount_pose
    return points_flange @ R_MH  # p_H = R_MH^T p_M


# --- tests ----------------------------------------------------------------------------------------------------


def test_the_description_is_vendored_unedited() -> None:
    for rel, blob in UPSTREAM_BLOBS.items():
        assert _git_blob(FOLDER / rel) == blob, rel


def test_the_official_description_loads_with_its_mimic_tags(adaptive: HandModel) -> None:
    assert len(adaptive.mimics) == 33 and {c.root for c in adaptive.mimics} == {SYNERGY}
    assert len(adaptive.synergy) == 34  # the synergy joint and its 33 mimics


def test_excluded_pairs_are_listed_with_their_reasons(adaptive: HandModel) -> None:
    pairs = {(p["body1"], p["body2"]): p["reason"] for p in hand_info(adaptive)["excluded_pairs"]}
    assert adaptive.model.nexclude == len(pairs) == len(adaptive.excluded)
    # across a virtual (massless, geometry-free) link: knuckle - fake_link1 - proximal
    assert pairs[("soft_hand_index_knuckle_link", "soft_hand_index_proximal_link")] == "adjacent"
    # across fixed links: the palm, the base, the clamp and the coupler are one rigid link the knuckles hang on
    assert pairs[("soft_hand_index_knuckle_link", "soft_hand_palm_link")] == "adjacent"
    assert pairs[("soft_hand_clamp", "soft_hand_thumb_knuckle_link")] == "adjacent"
    # pairs that only meet during the closure stay checked
    assert ("soft_hand_index_distal_link", "soft_hand_thumb_distal_link") not in pairs
    assert set(pairs.values()) == {"adjacent"}


def _hold(hand: HandModel, s: float, contacts: bool = True) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The hand after s ramps from 0 at the manifest's rate and is held 1 s (gravity off): both realisations
    are linear in s, so the closed controls scale with it."""
    held = dataclasses.replace(hand, closure_closed=hand.closure_open + s * (hand.closure_closed - hand.closure_open))
    model = copy.copy(hand.model)
    model.opt.gravity[:] = 0.0
    if not contacts:
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    data = prepare_data(held, model)
    run_closure(held, model, data, duration=s * hand.manifest.closure.duration, settle=1.0)
    return model, data


def _worst_joint_error(hand: HandModel, model: mujoco.MjModel, data: mujoco.MjData, s: float) -> float:
    """Largest |q - clip(multiplier * s)| [deg] over the coupled joints (the limits clip in both modes: the
    adaptive tendon pulls a joint against its stop)."""
    urdf = ET.fromstring(hand.expanded.xml)  # type: ignore[union-attr]
    return max(
        abs(math.degrees(float(data.qpos[model.jnt_qposadr[model.joint(j).id]]) - target))
        for j, target in fk_joint_values(urdf, s).items()
    )


def _reference_points(hand: HandModel, data: mujoco.MjData) -> np.ndarray:
    return to_hand_frame(hand, data, reference_points_world(hand, data))


@pytest.mark.parametrize("mode", ["kinematic", "adaptive"])
def test_synergy_closure_follows_the_mimic_tags_and_closes(
    mode: str, adaptive: HandModel, kinematic: HandModel
) -> None:
    hand = adaptive if mode == "adaptive" else kinematic
    for s in (0.25, 0.5):
        model, data = _hold(hand, s)
        assert data.ncon == 0
        assert _worst_joint_error(hand, model, data, s) < 3.0, s
    # at s = 1 the description's synergy (every flexion joint at its 45 deg limit, the thumb's abduction and
    # inner joint clipped) curls the fingertips into the palm and into each other, pairs that stay checked:
    # the joints follow multiplier * s when contacts are off, and the closed hand stops short of it
    model, data = _hold(hand, 1.0, contacts=False)
    assert _worst_joint_error(hand, model, data, 1.0) < 3.0
    traj = simulate_closure(hand, surface_points=0)
    ratio = spread(traj.positions[-1]) / spread(traj.positions[0])
    assert ratio <= 0.6, ratio


def test_the_description_synergy_pose_meets_itself_at_s_1(adaptive: HandModel) -> None:
    """Why s = 1 is not reached with contacts on: at the description's own joint values its collision meshes of
    non-adjacent links overlap (fingertips in the palm and in each other), none of them an excluded pair."""
    model, urdf = adaptive.model, ET.fromstring(adaptive.expanded.xml)  # type: ignore[union-attr]
    excluded = {(p.body1, p.body2) for p in adaptive.excluded}
    for s, expected in ((0.5, 0), (1.0, 1)):
        data = mujoco.MjData(model)
        for joint, q in fk_joint_values(urdf, s).items():
            data.qpos[model.jnt_qposadr[model.joint(joint).id]] = q
        mujoco.mj_forward(model, data)
        pairs = {tuple(sorted((model.body(model.geom_bodyid[c.geom1]).name, model.body(model.geom_bodyid[c.geom2]).name)))
                 for c in data.contact[: data.ncon] if c.dist < 0}  # fmt: skip
        assert not pairs & excluded
        assert (("soft_hand_index_distal_link", "soft_hand_thumb_distal_link") in pairs) == bool(expected), s


@pytest.mark.parametrize("mode", ["kinematic", "adaptive"])
def test_closure_signature_matches_the_description_kinematics(
    mode: str, adaptive: HandModel, kinematic: HandModel
) -> None:
    """The ellipsoid CS of a closure to s = 0.5 (no contact yet) against the CS of the description's forward
    kinematics at s = 0 and 0.5: its two largest deformations differ by 12 %, a well-defined axis. (At s = 1
    they differ by 0.5 %, and the blocked closure's axis is not the free kinematics'.)"""
    hand = adaptive if mode == "adaptive" else kinematic
    urdf = ET.fromstring(hand.expanded.xml)  # type: ignore[union-attr]
    expected = np.stack([fk_points(urdf, 0.0), fk_points(urdf, 0.5)])
    open_hand = prepare_data(hand, hand.model)
    np.testing.assert_allclose(_reference_points(hand, open_hand), expected[0], atol=1e-6)  # the same open hand
    _, data = _hold(hand, 0.5)
    got = np.stack([expected[0], _reference_points(hand, data)])
    cs, cs_fk = ellipsoid_closure_signature(got), ellipsoid_closure_signature(expected)
    angle = math.degrees(math.acos(min(1.0, abs(float(np.dot(cs.axis, cs_fk.axis))))))
    assert angle <= 10.0, (angle, cs.axis, cs_fk.axis)


# --- the rules on tiny descriptions ---------------------------------------------------------------------------

TINY_URDF = """<robot name="tiny">
  <link name="base"/>
  <link name="plate"><collision><geometry><box size="0.04 0.04 0.01"/></geometry></collision></link>
  <link name="virtual"/>
  <link name="finger"><collision><origin xyz="0 0 0.02"/><geometry><box size="0.01 0.01 0.02"/></geometry></collision>
    <inertial><mass value="0.01"/><inertia ixx="1e-6" iyy="1e-6" izz="1e-6" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tip"><collision><origin xyz="0 0 0.01"/><geometry><box size="0.01 0.01 0.01"/></geometry></collision>
    <inertial><mass value="0.01"/><inertia ixx="1e-6" iyy="1e-6" izz="1e-6" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="other"><collision><origin xyz="0 0 0.02"/><geometry><box size="0.01 0.01 0.02"/></geometry></collision>
    <inertial><mass value="0.01"/><inertia ixx="1e-6" iyy="1e-6" izz="1e-6" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="bolt" type="fixed"><parent link="base"/><child link="plate"/></joint>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="virtual"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="roll" type="revolute"><parent link="virtual"/><child link="finger"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="tip_joint" type="revolute"><parent link="finger"/><child link="tip"/><origin xyz="0 0 0.04"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="other_joint" type="revolute"><parent link="base"/><child link="other"/><origin xyz="0.006 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="1" effort="1" velocity="1"/></joint>
</robot>"""

TINY_SRDF = """<?xml version="1.0"?>
<robot name="tiny">
  <group name="hand"><link name="finger"/></group>
  <disable_collisions link1="tip" link2="plate" reason="Never"/>
  <disable_collisions link1="arm_link" link2="finger" reason="Adjacent"/>
</robot>"""


def test_adjacency_across_fixed_and_virtual_links() -> None:
    pairs = {(a, b): via for a, b, via in urdf_adjacent_pairs(TINY_URDF)}
    # plate is fixed to the geometry-free base: one rigid link, adjacent to finger through the virtual link
    # and to other directly; tip is adjacent to finger only; finger and other are siblings, not adjacent
    assert pairs == {
        ("finger", "plate"): "roll hinge",  # listed from the first link of the pair
        ("finger", "tip"): "tip_joint",
        ("other", "plate"): "other_joint",
    }


def test_srdf_disable_collisions_parsing() -> None:
    assert srdf_disabled_pairs(TINY_SRDF) == [("tip", "plate", "Never"), ("arm_link", "finger", "Adjacent")]
    from softsig_service.errors import InvalidHandModel

    with pytest.raises(InvalidHandModel):
        srdf_disabled_pairs('<robot><disable_collisions link1="a"/></robot>')
    with pytest.raises(InvalidHandModel):
        srdf_disabled_pairs("<robot>")


def test_a_tiny_hand_gets_all_three_reasons(tmp_path: Path) -> None:
    (tmp_path / "tiny.urdf").write_text(TINY_URDF, encoding="utf-8")
    (tmp_path / "config").mkdir()
    (tmp_path / "config" / "tiny.srdf").write_text(TINY_SRDF, encoding="utf-8")
    (tmp_path / "hand.toml").write_text(
        'name = "tiny"\nmodel = "tiny.urdf"\nmount = "base"\n'
        'reference_points = [{ name = "a_tip", body = "tip" }, { name = "b_tip", body = "other" },\n'
        '  { name = "c_tip", body = "finger" }, { name = "wrist", body = "base" }]\n'
        '[closure]\nkind = "posture"\nopen = { hinge = 0.0, roll = 0.0, tip_joint = 0.0, other_joint = 0.0 }\nclosed = { hinge = 0.5, roll = 0.0, tip_joint = 0.0, other_joint = 0.0 }\n',
        encoding="utf-8",
    )
    hand = load_hand(str(tmp_path / "hand.toml"), Settings())
    got = {(p.body1, p.body2): p.reason for p in hand.excluded}
    assert got == {
        ("finger", "plate"): "adjacent",
        ("finger", "tip"): "adjacent",
        ("other", "plate"): "adjacent",
        ("plate", "tip"): "srdf",  # arm_link is not a body of the hand: left out
        ("finger", "other"): "contact at open pose",  # other's box overlaps finger's at the open pose
    }
    assert hand.model.nexclude == 5
    data = mujoco.MjData(hand.model)
    mujoco.mj_forward(hand.model, data)
    assert data.ncon == 0
