"""The open hand's clearance to table and object: culled distances equal brute force; the descent stops at contact."""

from __future__ import annotations

import math

import coal
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.arm.shapes import HandShape, object_geometry
from softsig_service.geometry.transforms import make_transform, rot_x, rot_y
from softsig_service.objects import builtin_object
from softsig_service.planning.clearance import HandClearance
from softsig_service.planning.planner import planning_model
from softsig_service.planning.wrist_pose import hand_rotation


def _brute_force(hc: HandClearance, T: np.ndarray) -> tuple[float, float]:
    """Every shape against coal's half-space below z = 0 (its shape-to-plane distances are exact, also inside) and
    against the object."""
    table, at_origin = coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0), coal.Transform3s()
    obj = builtin_object("cylinder").with_pose(0.5, 0.0, 0.7)
    geo = object_geometry(obj.primitive())
    Tp = obj.primitive_pose
    req = coal.DistanceRequest()
    dt = do = math.inf
    for g, Ts in hc._shapes:
        W = T @ Ts
        tf = coal.Transform3s(W[:3, :3].copy(), W[:3, 3].copy())
        dt = min(dt, coal.distance(g, tf, table, at_origin, req, coal.DistanceResult()))
        do = min(do, coal.distance(g, tf, geo, coal.Transform3s(Tp[:3, :3].copy(), Tp[:3, 3].copy()),
                                   req, coal.DistanceResult()))  # fmt: skip
    return dt, do


def _clearance(hand: str) -> HandClearance:
    """The clearance of ``hand``'s open primitives to the table (z = 0) and the built-in cylinder of
    :func:`_brute_force`."""
    return HandClearance(planning_model(hand).shapes, builtin_object("cylinder").with_pose(0.5, 0.0, 0.7), 0.0)


def _flange_pose(x: float, y: float, z: float, yaw: float, roll: float, pitch: float) -> np.ndarray:
    """The flange pose at (x, y, z) [m] with the hand turned by (yaw, roll, pitch) [rad] from a top grasp."""
    T = np.eye(4)
    T[:3, :3] = hand_rotation(yaw, roll, pitch)
    T[:3, 3] = (x, y, z)
    return T


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(0.35, 0.65), y=st.floats(-0.15, 0.15), z=st.floats(0.05, 0.4),
    yaw=st.floats(-math.pi, math.pi), roll=st.floats(-0.2, 0.2), pitch=st.floats(-0.2, 0.2),
)  # fmt: skip
def test_culled_distances_equal_brute_force(
    x: float, y: float, z: float, yaw: float, roll: float, pitch: float
) -> None:
    hc = _clearance("rbo_hand2")
    T = _flange_pose(x, y, z, yaw, roll, pitch)
    np.testing.assert_allclose(hc.distances(T), _brute_force(hc, T), atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(0.4, 0.6), y=st.floats(-0.1, 0.1), z=st.floats(0.0, 0.5),
    yaw=st.floats(-math.pi, math.pi), roll=st.floats(-0.2, 0.2), pitch=st.floats(-0.2, 0.2),
)  # fmt: skip
def test_nearest_is_the_smaller_brute_force_distance_and_names_it(
    x: float, y: float, z: float, yaw: float, roll: float, pitch: float
) -> None:
    """The descent's query (coal asked only about shapes that could beat the table) gives min(table, object)
    exactly and which of the two it is, also at poses where the object is the nearer."""
    hc = _clearance("pisa_iit_softhand")
    T = _flange_pose(x, y, z, yaw, roll, pitch)
    d_table, d_obj = _brute_force(hc, T)
    d, which = hc.nearest(T)
    assert d == pytest.approx(min(d_table, d_obj), abs=1e-9)
    if abs(d_table - d_obj) > 1e-9:
        assert which == ("table" if d_table < d_obj else "object")
    # the full query after the nearest one at the same pose still gives both distances
    np.testing.assert_allclose(hc.distances(T), (d_table, d_obj), atol=1e-9)


def test_one_clearance_asked_at_many_orientations_in_turn_equals_brute_force() -> None:
    """The terms kept per orientation never leak into another: poses at ten orientations, asked in an
    interleaved order and again after translations, each equal brute force."""
    hc = _clearance("pisa_iit_softhand")
    rng = np.random.default_rng(3)
    rotations = [hand_rotation(*rng.uniform([-math.pi, -0.2, -0.2], [math.pi, 0.2, 0.2])) for _ in range(10)]
    for k in [0, 1, 0, 2, 3, 1, 4, 5, 6, 7, 8, 9, 0, 9, 5] * 2:
        T = np.eye(4)
        T[:3, :3] = rotations[k]
        T[:3, 3] = (rng.uniform(0.4, 0.6), rng.uniform(-0.1, 0.1), rng.uniform(0.05, 0.3))
        np.testing.assert_allclose(hc.distances(T), _brute_force(hc, T), atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(a=st.floats(-math.pi, math.pi), b=st.floats(-math.pi, math.pi), z=st.floats(-0.02, 0.3))
def test_the_table_distance_is_the_lowest_corner_or_rim(a: float, b: float, z: float) -> None:
    """Known answers: a box's lowest corner, a cylinder's lowest rim point and a capsule's lowest cap, in closed form
    for a box tilted about x then y (negative: below the table)."""
    R = rot_x(a) @ rot_y(b)
    hx, hy, hz, r, h = 0.02, 0.03, 0.01, 0.015, 0.04
    for shape, expected in (
        (HandShape("box", (hx, hy, hz)), np.abs(R[2]) @ (hx, hy, hz)),
        (HandShape("cylinder", (r, h)), abs(R[2, 2]) * h + r * math.hypot(R[2, 0], R[2, 1])),
        (HandShape("capsule", (r, h)), abs(R[2, 2]) * h + r),
        (HandShape("sphere", (r,)), r),
    ):
        hc = HandClearance([shape], None, 0.0)
        d_table, d_obj = hc.distances(make_transform(R, [0.4, 0.1, z]))
        assert d_table == pytest.approx(z - expected, abs=1e-12), shape.kind
        assert d_obj == math.inf


def test_descent_stops_at_the_margin_on_the_first_obstacle() -> None:
    shapes = planning_model("parallel_gripper").shapes
    obj = builtin_object("box").with_pose(0.5, 0.0, 0.0)
    hc = HandClearance(shapes, obj, 0.0)
    T = np.eye(4)
    T[:3, :3] = hand_rotation(0.0, 0.0, 0.0)  # jaws closing across world y, over the box's long side
    T[:3, 3] = (0.5, 0.0, 0.6)
    down = np.array([0.0, 0.0, -1.0])
    d = hc.descend(T, down, max_travel=1.0, margin=0.005)
    assert d.limited_by in ("table", "object")
    assert 0.005 - 1e-9 <= d.distance < 0.005 + 5e-4  # stops within the descent tolerance above the margin
    assert min(hc.distances(d.T_world_hand)) >= 0.005 - 1e-9
    # one more millimetre down would break the margin
    lower = d.T_world_hand.copy()
    lower[2, 3] -= 0.001
    assert min(hc.distances(lower)) < 0.005
    # a free path reports the travel limit
    short = hc.descend(T, down, max_travel=0.05, margin=0.005)
    assert short.limited_by == "travel" and short.travel == 0.05


def test_the_descent_starts_half_a_metre_above_the_object_for_both_strategies() -> None:
    """The start of the approach is START_HEIGHT above the object's centre along the approach, whatever the
    flange's offset from the centre (strategy C's NLP returns the flange below the anchor)."""
    from softsig_service.planning.planner import START_HEIGHT, Planner, PlanRequest

    planner = Planner()
    obj = builtin_object("box").with_pose(0.5, 0.1, 0.4)
    seen: list[float] = []
    original = HandClearance.descend

    def spy(self: HandClearance, T_start: np.ndarray, direction: np.ndarray, *args: object, **kw: object):  # type: ignore[no-untyped-def]
        seen.append(float((T_start[:3, 3] - obj.center) @ direction))
        return original(self, T_start, direction, *args, **kw)  # type: ignore[arg-type]

    HandClearance.descend = spy  # type: ignore[method-assign]
    try:
        for strategy in ("S", "C"):
            planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy=strategy))  # type: ignore[arg-type]
    finally:
        HandClearance.descend = original  # type: ignore[method-assign]
    assert seen and all(abs(s + START_HEIGHT) < 1e-9 for s in seen)
