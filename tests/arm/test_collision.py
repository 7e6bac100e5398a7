"""Collision world: arm links (convex hulls), table, object, hand shapes attached to tool0."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softsig_service.arm.collision import CollisionWorld
from softsig_service.arm.collision_report import REASON_OBJECT, REASON_SELF, REASON_TABLE
from softsig_service.arm.shapes import HandKind, HandShape, ObjectKind, ObjectShape
from softsig_service.arm.ur5 import UR5, load_ur5
from softsig_service.errors import InvalidInput
from softsig_service.geometry.transforms import apply, make_transform, rot_x, rot_y, rot_z
from softsig_service.objects import builtin_object

# a small hand in the tool0 frame: a palm and two fingers reaching 0.12 m out of the flange
HAND = (
    HandShape("box", (0.04, 0.05, 0.02), make_transform(None, [0.0, 0.0, 0.02]), name="palm"),
    HandShape("capsule", (0.01, 0.03), make_transform(None, [0.0, 0.035, 0.08]), name="finger_a"),
    HandShape("capsule", (0.01, 0.03), make_transform(None, [0.0, -0.035, 0.08]), name="finger_b"),
)
HAND_REACH = 0.12  # [m] beyond the flange along tool0 z


def down(x: float, y: float, z: float, yaw: float = 0.0) -> np.ndarray:
    """tool0 at (x, y, z) pointing down (top grasp)."""
    return make_transform(rot_z(yaw) @ rot_x(math.pi), [x, y, z])


@pytest.fixture(scope="module")
def ur5() -> UR5:
    return load_ur5()


@pytest.fixture(scope="module")
def q_above(ur5: UR5) -> np.ndarray:
    """Flange 0.35 m above the table, pointing down, in front of the robot."""
    res = ur5.solve_ik(down(0.5, 0.1, 0.35), np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0]))
    assert res.success
    return res.q


def ik(ur5: UR5, T: np.ndarray, near: np.ndarray) -> np.ndarray:
    res = ur5.solve_ik(T, near)
    assert res.success
    return res.q


def test_pairs_follow_the_srdf_and_exclusions(ur5: UR5) -> None:
    world = CollisionWorld(ur5, HAND)
    pairs = world.pair_names
    self_arm = [p for p in pairs if p[2] == "self" and not p[0].startswith("hand:") and not p[1].startswith("hand:")]
    assert len(self_arm) == 17  # 27 -> 17 after the SRDF (example-robot-data srdf/ur5.srdf)
    table = {p[0] for p in pairs if p[2] == "table"}
    assert "base_link" not in table and "shoulder_link" not in table
    assert {"upper_arm_link", "wrist_3_link", "hand:palm", "hand:finger_a"} <= table
    hand_arm = {p[0] for p in pairs if p[2] == "self" and p[1] == "hand:palm"}
    assert "wrist_3_link" not in hand_arm and "ee_link" not in hand_arm and "forearm_link" in hand_arm
    assert not any(p[2] == "object" for p in pairs)  # no object yet


def test_normal_pose_above_the_table_is_free(ur5: UR5, q_above: np.ndarray) -> None:
    world = CollisionWorld(ur5, HAND)
    rep = world.check(q_above)
    assert not rep.in_collision and rep.reasons == [] and rep.reason is None
    assert rep.min_distance_hand_table is not None
    # the finger tips are 0.35 - 0.12 = 0.23 m above the table (capsule end: 0.08 + 0.03 + 0.01)
    assert rep.min_distance_hand_table == pytest.approx(0.35 - HAND_REACH, abs=2e-3)
    assert rep.min_distance_table is not None and 0.0 < rep.min_distance_table <= rep.min_distance_hand_table


def test_flange_driven_into_the_table_is_caught(ur5: UR5, q_above: np.ndarray) -> None:
    bare = CollisionWorld(ur5)
    q_low = ik(ur5, down(0.5, 0.1, -0.02), q_above)  # flange 2 cm below the table top
    rep = bare.check(q_low)
    assert rep.in_collision and rep.reason == REASON_TABLE
    assert ("wrist_3_link", "table") in rep.pairs
    assert rep.min_distance_table is not None and rep.min_distance_table < -0.01
    # with the hand, a flange 5 cm above the table pushes the fingers 7 cm into it
    world = CollisionWorld(ur5, HAND)
    q_hand = ik(ur5, down(0.5, 0.1, 0.05), q_above)
    rep = world.check(q_hand)
    assert rep.reasons == [REASON_TABLE]
    assert ("hand:finger_a", "table") in rep.pairs and ("hand:finger_b", "table") in rep.pairs
    assert rep.min_distance_hand_table == pytest.approx(0.05 - HAND_REACH, abs=2e-3)
    assert not bare.check(q_hand).in_collision  # the bare flange clears the table there
    # a caller that has shown the hand clear of the table may leave its pairs out; the arm's stay
    assert not world.check(q_hand, ignore_hand_table=True).in_collision
    rep = world.check(np.zeros(6), ignore_hand_table=True)  # the wrist on the table is still caught
    assert rep.reasons == [REASON_TABLE] and all(not a.startswith("hand:") for a, _ in rep.pairs)


def test_q_zero_lies_on_the_table(ur5: UR5) -> None:
    # at q = 0 the flange is at z = -0.0055 m: the wrist dips below the table top
    rep = CollisionWorld(ur5).check(np.zeros(6))
    assert rep.reasons == [REASON_TABLE]
    assert ("wrist_2_link", "table") in rep.pairs


def test_table_height_and_table_margin(ur5: UR5, q_above: np.ndarray) -> None:
    high = CollisionWorld(ur5, HAND, table_height=0.30)
    assert high.check(q_above).reason == REASON_TABLE
    world = CollisionWorld(ur5, HAND)
    clear = world.check(q_above).min_distance_hand_table
    assert clear is not None
    # the upper arm's shoulder end stays ~0.03 m above the table, so only margins below that are usable
    assert not world.check(q_above, table_margin=0.02).in_collision
    assert world.check(q_above, table_margin=0.05).reason == REASON_TABLE
    with pytest.raises(InvalidInput):
        world.check(q_above, margin=-0.1)


def test_hand_overlapping_the_object_is_caught(ur5: UR5, q_above: np.ndarray) -> None:
    world = CollisionWorld(ur5, HAND)
    T_flange = ur5.fk(q_above)
    centre = apply(T_flange, [0.0, 0.0, 0.10])  # between the fingers' tips
    world.set_object(ObjectShape("box", (0.03, 0.03, 0.03)), make_transform(rot_z(0.3), centre))
    rep = world.check(q_above)
    assert rep.in_collision and rep.reasons == [REASON_OBJECT]
    assert ("hand:finger_a", "object") in rep.pairs
    assert all(a.startswith("hand:") for a, b in rep.pairs)
    assert rep.min_distance_hand_object is not None and rep.min_distance_hand_object < 0.0
    # at a grasp the hand is meant to touch the object: the caller may ignore those pairs
    rep = world.check(q_above, ignore_hand_object=True)
    assert not rep.in_collision
    assert rep.min_distance_object is not None and rep.min_distance_object > 0.0
    assert rep.min_distance_hand_object is None
    world.clear_object()
    assert not world.check(q_above).in_collision and not world.has_object


def test_hand_shapes_ride_on_tool0(ur5: UR5, q_above: np.ndarray) -> None:
    """Distance between a hand sphere and an object sphere equals the analytic value."""
    ball = HandShape("sphere", (0.02,), make_transform(rot_y(0.4), [0.01, -0.02, 0.10]), name="ball")
    world = CollisionWorld(ur5, [ball])
    T_flange = ur5.fk(q_above)
    hand_centre = apply(T_flange, [0.01, -0.02, 0.10])
    obj_centre = apply(T_flange, [0.05, 0.03, 0.20])
    world.set_object(ObjectShape("sphere", (0.03,)), make_transform(None, obj_centre))
    rep = world.check(q_above)
    expected = float(np.linalg.norm(obj_centre - hand_centre)) - 0.05
    assert rep.min_distance_hand_object == pytest.approx(expected, abs=1e-6)
    assert not rep.in_collision
    assert world.check(q_above, margin=expected + 1e-3).reasons == [REASON_OBJECT]
    assert not world.check(q_above, margin=expected - 1e-3).in_collision
    # the wrist links sit a few cm apart: a self margin of 5 cm flags them, the object margin does not
    assert world.check(q_above, self_margin=0.05).reasons == [REASON_SELF]


def test_arm_against_the_object(ur5: UR5, q_above: np.ndarray) -> None:
    world = CollisionWorld(ur5, HAND)
    # an object around the forearm: not a hand pair, so ignore_hand_object does not hide it
    forearm = ur5.frame_pose(q_above, "forearm_link")
    world.set_object(ObjectShape("sphere", (0.05,)), make_transform(None, apply(forearm, [0.0, 0.0, 0.2])))
    rep = world.check(q_above, ignore_hand_object=True)
    assert rep.reasons == [REASON_OBJECT]
    assert ("forearm_link", "object") in rep.pairs


def test_folded_elbow_is_a_self_collision(ur5: UR5) -> None:
    world = CollisionWorld(ur5, HAND)
    rep = world.check(np.array([0.0, -math.pi / 2, 2.8, 0.0, 0.0, 0.0]))
    assert REASON_SELF in rep.reasons and REASON_TABLE not in rep.reasons
    assert ("upper_arm_link", "wrist_2_link") in rep.pairs
    assert world.check(np.array([0.0, -math.pi / 2, 2.8, 0.0, 0.0, 0.0]), check_self=False).reasons == []


def test_collision_agrees_with_distance_for_random_primitives(ur5: UR5, q_above: np.ndarray) -> None:
    """Guards the coal collision query (with contacts) against its own signed distance."""
    rng = np.random.default_rng(2)
    T_flange = ur5.fk(q_above)
    sizes = {"box": 3, "capsule": 2, "sphere": 1, "cylinder": 2, "ellipsoid": 3}
    disagreements = 0
    for i in range(120):
        kind_h: HandKind = ("box", "capsule", "sphere", "cylinder")[i % 4]
        kind_o: ObjectKind = ("box", "cylinder", "sphere", "ellipsoid")[(i // 4) % 4]
        shape = HandShape(
            kind_h,
            tuple(rng.uniform(0.01, 0.04, sizes[kind_h])),
            make_transform(rot_x(rng.uniform(-3, 3)) @ rot_y(rng.uniform(-3, 3)), [0.0, 0.0, 0.1]),
            name="s",
        )
        world = CollisionWorld(ur5, [shape])
        centre = apply(T_flange, [0.0, 0.0, 0.1]) + rng.uniform(-0.06, 0.06, 3)
        pose = make_transform(rot_z(rng.uniform(-3, 3)) @ rot_x(rng.uniform(-3, 3)), centre)
        world.set_object(ObjectShape(kind_o, tuple(rng.uniform(0.01, 0.04, sizes[kind_o]))), pose)
        rep = world.check(q_above, check_table=False, check_self=False)
        d = rep.min_distance_hand_object
        assert d is not None
        hit = ("hand:s", "object") in rep.pairs
        if abs(d) > 1e-5 and hit != (d < 0.0):
            disagreements += 1
    assert disagreements == 0


def test_capsule_on_a_box_face(ur5: UR5, q_above: np.ndarray) -> None:
    """A capsule whose core segment lies on a box face overlaps it by its radius (coal 3.0.3 misses this
    without contact computation)."""
    cap = HandShape("capsule", (0.01, 0.04), make_transform(rot_y(math.pi / 2), [0.0, 0.0, 0.1]), name="cap")
    world = CollisionWorld(ur5, [cap])
    T_cap = ur5.fk(q_above) @ make_transform(rot_y(math.pi / 2), [0.0, 0.0, 0.1])
    # box face y = -0.03 through the capsule's axis
    world.set_object(ObjectShape("box", (0.03, 0.03, 0.03)), T_cap @ make_transform(None, [0.0, 0.03, 0.0]))
    rep = world.check(q_above, check_table=False, check_self=False)
    assert rep.in_collision and ("hand:cap", "object") in rep.pairs


def test_paths(ur5: UR5, q_above: np.ndarray) -> None:
    world = CollisionWorld(ur5, HAND)
    q_low = ik(ur5, down(0.5, 0.1, 0.05), q_above)
    rep = world.check_path(q_above, q_low, steps=10)
    assert rep.in_collision and rep.reason == REASON_TABLE
    assert rep.waypoint is not None and 0 < rep.waypoint <= 10
    assert rep.checked == rep.waypoint + 1
    q_mid = ik(ur5, down(0.5, 0.1, 0.25), q_above)
    free = world.check_path(q_above, q_mid, steps=5)
    assert not free.in_collision and free.checked == 6 and free.waypoint is None
    # a straight Cartesian approach, as IK waypoints
    qs = [q_above]
    for z in np.linspace(0.35, 0.0, 8)[1:]:
        qs.append(ik(ur5, down(0.5, 0.1, float(z)), qs[-1]))
    rep = world.check_waypoints(qs, stop_at_first=False)
    first = rep.waypoint
    assert first is not None
    # the hand reaches the table once the flange is lower than HAND_REACH
    zs = np.linspace(0.35, 0.0, 8)
    assert zs[first] < HAND_REACH <= zs[first - 1] + 1e-9
    assert rep.checked == 8


def test_table_objects_plug_in(ur5: UR5) -> None:
    """A lying cylinder from planning.objects: its axis is the object's x (the coal cylinder's is its z)."""
    cyl = builtin_object("cylinder", x=0.5, y=0.1, yaw=0.5)  # radius 0.03, half-length 0.08
    tip = HandShape("sphere", (0.005,), make_transform(None, [0.0, 0.0, 0.1]), name="tip")
    world = CollisionWorld(ur5, [tip])
    world.set_object(cyl.primitive(), cyl.primitive_pose)
    seed = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])
    # tip centre placed on the axis line (along o1) or across it (along o2), at the axis height
    cases = [
        (cyl.o1, 0.06, None),  # inside the cylinder
        (cyl.o1, 0.095, 0.095 - 0.08 - 0.005),  # beyond the flat end cap
        (cyl.o2, 0.05, 0.05 - 0.03 - 0.005),  # beside the curved side
    ]
    for axis, offset, expected in cases:
        p = cyl.center + offset * axis + np.array([0.0, 0.0, 0.1])  # the flange, 0.1 m above the tip
        q = ik(ur5, down(*p), seed)
        assert np.allclose(apply(ur5.fk(q), [0.0, 0.0, 0.1]), cyl.center + offset * axis, atol=1e-4)
        rep = world.check(q, check_table=False, check_self=False)
        if expected is None:
            assert ("hand:tip", "object") in rep.pairs
        else:
            assert not rep.in_collision
            assert rep.min_distance_hand_object == pytest.approx(expected, abs=1e-4)


def test_bad_shapes_are_rejected(ur5: UR5) -> None:
    with pytest.raises(InvalidInput) as info:
        HandShape("box", (0.1, 0.1))
    assert info.value.field == "hand_shape.size"
    with pytest.raises(InvalidInput) as info:
        HandShape("cone", (0.1, 0.1))  # type: ignore[arg-type]
    assert info.value.field == "hand_shape.kind" and info.value.choices is not None
    with pytest.raises(InvalidInput):
        HandShape("sphere", (-0.1,))
    world = CollisionWorld(ur5)
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    with pytest.raises(InvalidInput, match="coplanar"):
        world.set_object(ObjectShape("mesh", (), flat), np.eye(4))
    with pytest.raises(InvalidInput):
        world.set_object(ObjectShape("sphere", (math.nan,)), np.eye(4))
    with pytest.raises(InvalidInput):
        world.check(np.full(6, np.nan))


def test_moving_the_same_object_updates_its_pose() -> None:
    """set_object with an unchanged shape only moves it; the checks follow the new pose."""
    from softsig_service.arm.collision import CollisionWorld
    from softsig_service.arm.shapes import HandShape, ObjectShape
    from softsig_service.arm.ur5 import HOME_Q, load_ur5

    ur5 = load_ur5()
    world = CollisionWorld(ur5, [HandShape("box", (0.03, 0.03, 0.03), np.eye(4), "palm")])
    q = np.asarray(HOME_Q)
    flange = ur5.fk(q)[:3, 3]
    box = ObjectShape("box", (0.02, 0.02, 0.02))
    far = np.eye(4)
    far[:3, 3] = flange + np.array([0.0, 0.3, 0.0])
    world.set_object(box, far)
    assert not world.check(q).in_collision
    near = np.eye(4)
    near[:3, 3] = flange + np.array([0.0, 0.0, 0.03])
    world.set_object(box, near)
    report = world.check(q)
    assert "collision:object" in report.reasons
    world.set_object(box, far)
    assert not world.check(q).in_collision
