"""The MuJoCo validation scene: UR5 from the URDF, hand at tool0, table, free object, contact classes, caching."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from softsig_service.arm.ur5 import HOME_Q, JOINT_NAMES, load_ur5
from softsig_service.hands.model import SERVO_PREFIX, load_hand
from softsig_service.objects import box, builtin_object, cylinder, mesh
from softsig_service.simulation.scene import build_scene
from softsig_service.simulation.scene_model import ARM_KP, ARM_KV, GEOM_ARM, GEOM_HAND, GEOM_OBJECT, HAND_PREFIX, Scene

HANDS = ("pisa_iit_softhand", "parallel_gripper", "sdm_hand", "rbo_hand2")


@pytest.fixture(scope="module")
def softhand_box() -> Scene:
    return build_scene("pisa_iit_softhand", builtin_object("box"))


@pytest.mark.parametrize("hand", HANDS)
def test_hand_mount_is_the_ur5_flange(hand: str) -> None:
    """The hand's mount body coincides with tool0, and tool0 matches Pinocchio's FK of the same URDF."""
    scene = build_scene(hand, builtin_object("box"))
    ur5 = load_ur5()
    rng = np.random.default_rng(3)
    for _ in range(3):
        q = ur5.random_configuration(rng)
        data = scene.make_data(q, builtin_object("box").primitive_pose)
        T_sim = scene.flange_pose(data)
        assert np.allclose(T_sim, ur5.fk(q), atol=1e-9)
        assert np.allclose(data.xpos[scene.mount_body], data.xpos[scene.flange_body], atol=1e-12)
        assert np.allclose(data.xmat[scene.mount_body], data.xmat[scene.flange_body], atol=1e-12)
    # every hand body, joint and actuator is there, prefixed
    alone = load_hand(hand).model
    for j in range(alone.njnt):
        name = alone.joint(j).name
        sj = scene.model.joint(HAND_PREFIX + name)
        assert np.allclose(sj.range, alone.joint(j).range)
    assert scene.model.nu == 6 + alone.nu


def test_closure_actuators_map_onto_the_hand(softhand_box: Scene) -> None:
    hand = softhand_box.hand
    names = [softhand_box.model.actuator(int(a)).name for a in softhand_box.closure_actuators]
    assert names == [HAND_PREFIX + hand.model.actuator(a).name for a in hand.closure_actuators]
    assert np.array_equal(softhand_box.closure_open, hand.closure_open)
    assert np.array_equal(softhand_box.closure_closed, hand.closure_closed)


def test_posture_closure_servos_are_attached_too() -> None:
    scene = build_scene("parallel_gripper", builtin_object("box"))
    names = [scene.model.actuator(int(a)).name for a in scene.closure_actuators]
    assert len(names) == 2 and all(n.startswith(HAND_PREFIX + SERVO_PREFIX) for n in names)
    data = scene.make_data(np.array(HOME_Q), builtin_object("box").primitive_pose)
    for adr, value in scene.posture_qpos:
        assert data.qpos[adr] == pytest.approx(value)
    # the servos move the jaws: ramp to closed in free space (object far below)
    data.ctrl[scene.closure_actuators] = scene.closure_closed
    for _ in range(500):
        mujoco.mj_step(scene.model, data)
    assert all(abs(data.qpos[adr]) < 0.005 for adr, _ in scene.posture_qpos)


def test_arm_servos_gains_and_gravity_compensation(softhand_box: Scene) -> None:
    m = softhand_box.model
    for k, name in enumerate(JOINT_NAMES):
        a = m.actuator(f"arm_{name}")
        assert a.gainprm[0] == pytest.approx(ARM_KP[k])
        assert a.biasprm[1] == pytest.approx(-ARM_KP[k]) and a.biasprm[2] == pytest.approx(-ARM_KV[k])
    # the arm holds HOME_Q under gravity (hand attached) within 1 mm at the flange
    q = np.array(HOME_Q)
    obj = builtin_object("box", x=0.3, y=-0.3)
    data = softhand_box.make_data(q, obj.primitive_pose)
    T0 = softhand_box.flange_pose(data)
    for _ in range(500):
        mujoco.mj_step(m, data)
    assert np.linalg.norm(softhand_box.flange_pose(data)[:3, 3] - T0[:3, 3]) < 1e-3


def test_object_is_a_free_body_with_mass_and_friction_resting_on_the_table(softhand_box: Scene) -> None:
    m = softhand_box.model
    obj = builtin_object("box", yaw=0.4)
    assert m.body_mass[softhand_box.object_body] == pytest.approx(obj.mass)
    g = int(softhand_box.object_geoms[0])
    assert m.geom_friction[g][0] == pytest.approx(obj.friction)
    assert np.allclose(m.geom_size[g], [0.08, 0.03, 0.025])
    data = softhand_box.make_data(np.array(HOME_Q), obj.primitive_pose)
    for _ in range(250):
        mujoco.mj_step(m, data)
    p = softhand_box.object_position(data)
    assert p[2] == pytest.approx(0.025, abs=5e-4)  # rests on the table top (z = 0)
    assert np.allclose(p[:2], [0.5, 0.0], atol=1e-4)
    R = data.xmat[softhand_box.object_body].reshape(3, 3)
    assert math.atan2(R[1, 0], R[0, 0]) == pytest.approx(0.4, abs=1e-3)


def test_lying_cylinder_and_mesh_objects() -> None:
    cyl = cylinder(0.03, 0.16, 0.2)
    scene = build_scene("parallel_gripper", cyl)
    data = scene.make_data(np.array(HOME_Q), cyl.primitive_pose)
    R = data.xmat[scene.object_body].reshape(3, 3)
    assert abs(R[:, 2] @ np.array([1.0, 0.0, 0.0])) == pytest.approx(1.0)  # the primitive's z lies along x
    V = np.array([[-0.03, -0.02, -0.02], [0.03, -0.02, -0.02], [0.0, 0.03, -0.02], [0.0, 0.0, 0.02]])
    F = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    tet = mesh(V, F, 0.1)
    scene = build_scene("parallel_gripper", tet)
    assert scene.model.geom_type[scene.object_geoms[0]] == mujoco.mjtGeom.mjGEOM_MESH
    assert scene.model.body_mass[scene.object_body] == pytest.approx(0.1)


def test_scenes_are_cached_per_shape_not_per_pose() -> None:
    a = build_scene("pisa_iit_softhand", builtin_object("box", x=0.4, yaw=1.0))
    b = build_scene("pisa_iit_softhand", builtin_object("box", x=0.6, y=0.1))
    c = build_scene("pisa_iit_softhand", box((0.1, 0.06, 0.05), 0.15))
    assert a is b
    assert c is not a


def test_contact_classes(softhand_box: Scene) -> None:
    """Object-hand contact and arm-table contact are told apart; arm-hand and arm-arm never collide."""
    m = softhand_box.model
    cls = softhand_box.geom_class
    assert set(cls[softhand_box.hand_geoms]) == {GEOM_HAND}
    assert set(cls[softhand_box.arm_geoms]) == {GEOM_ARM}
    assert set(cls[softhand_box.object_geoms]) == {GEOM_OBJECT}
    for g in softhand_box.arm_geoms:
        for h in softhand_box.hand_geoms:
            collide = (m.geom_contype[g] & m.geom_conaffinity[h]) or (m.geom_contype[h] & m.geom_conaffinity[g])
            assert not collide
    ur5 = load_ur5()
    q = np.array(HOME_Q)
    data = softhand_box.make_data(q, builtin_object("box").primitive_pose)
    assert softhand_box.contact_summary(data) == (False, False, False, False, True)
    # the object overlapping the middle fingertip (hand +z points down at HOME_Q): contact with the hand
    tip = softhand_box.model.site(HAND_PREFIX + "middle_tip").id
    T = np.eye(4)
    T[:3, 3] = data.site_xpos[tip] + np.array([0.0, 0.0, -0.02])
    softhand_box.set_object_pose(data, T)
    mujoco.mj_forward(m, data)
    assert softhand_box.contact_summary(data).object_hand
    # the arm folded into the table: arm contact
    q_low = np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0])
    assert ur5.frame_pose(q_low, "forearm_link")[2, 3] < 0.0
    data = softhand_box.make_data(q_low, builtin_object("box", x=0.3, y=-0.5).primitive_pose)
    assert softhand_box.contact_summary(data)[:4] == (False, True, False, False)
    # the object on the forearm
    T = ur5.frame_pose(np.array(HOME_Q), "forearm_link")
    data = softhand_box.make_data(np.array(HOME_Q), T)
    assert softhand_box.contact_summary(data).arm_object
