"""The broad phase never changes a verdict: the pairs reported colliding equal coal's verdict on every pair."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from softsig_service.arm.collision import CollisionWorld
from softsig_service.arm.shapes import HandShape, ObjectShape
from softsig_service.arm.ur5 import UR5, load_ur5
from softsig_service.geometry.transforms import make_transform, rot_x, rot_z
from softsig_service.planning.hand_model import planning_model

HAND = (
    HandShape("box", (0.04, 0.05, 0.02), make_transform(None, [0.0, 0.0, 0.02]), name="palm"),
    HandShape("capsule", (0.01, 0.03), make_transform(rot_x(0.4), [0.0, 0.035, 0.08]), name="finger_a"),
    HandShape("cylinder", (0.012, 0.03), make_transform(None, [0.0, -0.035, 0.08]), name="finger_b"),
    HandShape("sphere", (0.015,), make_transform(None, [0.02, 0.0, 0.12]), name="tip"),
)


@pytest.fixture(scope="module")
def ur5() -> UR5:
    return load_ur5()


def _all_pairs(world: CollisionWorld, q: np.ndarray) -> list[tuple[str, str]]:
    """coal's verdict on every pair of the world (no broad phase)."""
    w = world._w
    pin.updateGeometryPlacements(world._model, world._data, w.gm, w.gd, q)
    return [p.names for p in w.pairs if pin.computeCollision(w.gm, w.gd, p.index)]


@pytest.mark.parametrize("hand", ["small", "pisa_iit_softhand"])
def test_broad_phase_keeps_every_colliding_pair(ur5: UR5, hand: str) -> None:
    shapes = HAND if hand == "small" else planning_model(hand).shapes
    world = CollisionWorld(ur5, shapes, table_height=0.0, margin=0.01, table_margin=0.005, self_margin=0.002)
    rng = np.random.default_rng(7)
    objects = [
        (ObjectShape("box", (0.03, 0.05, 0.04)), make_transform(rot_z(0.3), [0.45, 0.1, 0.04])),
        (ObjectShape("cylinder", (0.04, 0.06)), make_transform(rot_x(math.pi / 2), [0.4, -0.1, 0.04])),
        (ObjectShape("sphere", (0.05,)), make_transform(None, [0.35, 0.0, 0.3])),
    ]
    collided = free = 0
    for k in range(300):
        shape, pose = objects[k % len(objects)]
        world.set_object(shape, pose)
        if k % 2:
            q = ur5.random_configuration(rng)
        else:  # the flange near the object, pointing down: hand/object and hand/table contacts
            target = make_transform(rot_z(rng.uniform(-math.pi, math.pi)) @ rot_x(math.pi), pose[:3, 3])
            target[:3, 3] += (rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), rng.uniform(0.0, 0.2))
            res = ur5.solve_ik(target, np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0]))
            q = res.q
        report = world.check(q, distances=False)
        expected = _all_pairs(world, q)
        assert sorted(report.pairs) == sorted(expected), k
        collided += bool(expected)
        free += not expected
    assert collided > 50 and free > 50  # both verdicts were exercised


def test_alternating_objects_reuse_their_worlds_and_answer_like_fresh_ones(ur5: UR5) -> None:
    """A world keeps one geometry model per object shape: switching back to an object (at a new pose) answers
    exactly as a world built for it alone."""
    world = CollisionWorld(ur5, HAND, table_height=0.0, margin=0.01)
    shapes = [
        ObjectShape("box", (0.03, 0.05, 0.04)),
        ObjectShape("sphere", (0.05,)),
        ObjectShape("box", (0.1, 0.02, 0.02)),
    ]
    rng = np.random.default_rng(11)
    for k in range(60):
        shape = shapes[k % len(shapes)]
        pose = make_transform(rot_z(rng.uniform(-1, 1)), [rng.uniform(0.3, 0.6), rng.uniform(-0.2, 0.2), 0.05])
        world.set_object(shape, pose)
        fresh = CollisionWorld(ur5, HAND, table_height=0.0, margin=0.01)
        fresh.set_object(shape, pose)
        target = make_transform(rot_z(rng.uniform(-math.pi, math.pi)) @ rot_x(math.pi), pose[:3, 3])
        target[:3, 3] += (rng.uniform(-0.04, 0.04), rng.uniform(-0.04, 0.04), rng.uniform(0.0, 0.15))
        q = ur5.solve_ik(target, np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])).q
        a, b = world.check(q), fresh.check(q)
        assert (a.pairs, a.reasons) == (b.pairs, b.reasons)
        # distances to 1e-6 m: coal's GJK/EPA start from the previous query's answer, so a world's distances depend
        # on its history by up to ~4e-7 m (measured on one world with and without an earlier query)
        assert a.min_distance_object == pytest.approx(b.min_distance_object, abs=1e-6)
        assert a.min_distance_table == pytest.approx(b.min_distance_table, abs=1e-6)
    assert len(world._built) == len(shapes)


@pytest.mark.parametrize("hand", ["small", "pisa_iit_softhand"])
@pytest.mark.parametrize("ignore_hand", [False, True])
def test_verdict_only_checks_agree_with_coal_on_every_pair(ur5: UR5, hand: str, ignore_hand: bool) -> None:
    """Without distances, waypoints are checked by Pinocchio's broad-phase manager in one call each; the verdict
    and the pairs reported are those of the pair-by-pair check, margins and left-out pairs included."""
    shapes = HAND if hand == "small" else planning_model(hand).shapes
    world = CollisionWorld(ur5, shapes, table_height=0.0, margin=0.01, table_margin=0.005, self_margin=0.002)
    rng = np.random.default_rng(5)
    shape, pose = ObjectShape("box", (0.03, 0.05, 0.04)), make_transform(rot_z(0.3), [0.45, 0.1, 0.04])
    world.set_object(shape, pose)
    collided = free = 0
    for k in range(240):
        if k % 2:
            q = ur5.random_configuration(rng)
        else:
            target = make_transform(rot_z(rng.uniform(-math.pi, math.pi)) @ rot_x(math.pi), pose[:3, 3])
            target[:3, 3] += (rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), rng.uniform(0.0, 0.2))
            q = ur5.solve_ik(target, np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])).q
        report = world.check_waypoints(
            [q], distances=False, ignore_hand_object=ignore_hand, ignore_hand_table=ignore_hand
        )
        # check() asks every selected pair the bounding volumes keep (the test above: the same as all pairs)
        expected = world.check(q, distances=False, ignore_hand_object=ignore_hand, ignore_hand_table=ignore_hand).pairs
        assert sorted(report.pairs) == sorted(expected), k
        assert report.in_collision == bool(expected)
        collided += bool(expected)
        free += not expected
    assert collided > 40 and free > 40
    assert world._w.managers[(True, True, True, ignore_hand, ignore_hand)] is not None  # the manager answered


def test_verdict_only_checks_follow_moves_shapes_and_margins(ur5: UR5) -> None:
    """The broad-phase manager answers like the pair-by-pair check when the object moves, when the world switches
    to another shape and back, without an object, with margins that change from call to call, and over a whole
    path (``stop_at_first=False``: every colliding waypoint's pairs)."""
    world = CollisionWorld(ur5, HAND, table_height=0.0)
    shapes = [ObjectShape("box", (0.03, 0.05, 0.04)), ObjectShape("sphere", (0.05,)), None]
    rng = np.random.default_rng(13)
    collided = 0
    for k in range(90):
        shape = shapes[k % 3]
        centre = np.array([rng.uniform(0.35, 0.55), rng.uniform(-0.15, 0.15), 0.05])
        if shape is None:
            world.clear_object()
        else:
            world.set_object(shape, make_transform(rot_z(rng.uniform(-1.0, 1.0)), centre))
        margins = {"margin": float(rng.uniform(0.0, 0.03)), "table_margin": float(rng.uniform(0.0, 0.01))}
        qs = []
        offset = np.array([rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), 0.0])
        for z in np.linspace(0.35, rng.uniform(0.05, 0.3), 4):
            target = make_transform(rot_z(rng.uniform(-math.pi, math.pi)) @ rot_x(math.pi), centre + offset + [0, 0, z])
            qs.append(ur5.solve_ik(target, np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])).q)
        report = world.check_waypoints(qs, distances=False, stop_at_first=False, **margins)
        expected = [world.check(q, distances=False, **margins) for q in qs]
        hit = [i for i, r in enumerate(expected) if r.in_collision]
        assert report.in_collision == bool(hit) and report.waypoint == (hit[0] if hit else None), k
        assert sorted(report.pairs) == sorted({p for r in expected for p in r.pairs}), k
        collided += bool(hit)
    assert 10 < collided < 80  # both verdicts exercised
    assert all(m is not None for m in world._w.managers.values()) and world._w.managers
