"""A mesh's hull and principal axes are built once per content, and moving a mesh keeps them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softsig_service.arm.shapes import object_geometry
from softsig_service.errors import InvalidInput
from softsig_service.objects import mesh
from softsig_service.planning import Planner, PlanRequest


def _ellipsoid(rings: int, radii: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """A closed UV ellipsoid: ``rings`` rings of ``s = rings + 2`` vertices and two poles."""
    s = rings + 2
    th = np.linspace(0.0, math.pi, rings + 2)[1:-1, None]
    ph = np.linspace(0.0, 2.0 * math.pi, s, endpoint=False)[None, :]
    ring = np.stack(np.broadcast_arrays(np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)), -1)
    V = np.vstack([[0.0, 0.0, 1.0], ring.reshape(-1, 3), [0.0, 0.0, -1.0]]) * np.asarray(radii)

    def idx(r: int, k: int) -> int:
        return 1 + r * s + k % s

    F = [(0, idx(0, k), idx(0, k + 1)) for k in range(s)]
    F += [(len(V) - 1, idx(rings - 1, k + 1), idx(rings - 1, k)) for k in range(s)]
    for r in range(rings - 1):
        for k in range(s):
            F += [(idx(r, k), idx(r + 1, k), idx(r + 1, k + 1)), (idx(r, k), idx(r + 1, k + 1), idx(r, k + 1))]
    return V, np.asarray(F)


def test_moving_a_mesh_keeps_its_digest_axes_and_hull() -> None:
    V, F = _ellipsoid(12, (0.05, 0.03, 0.035))
    obj = mesh(V, F, 0.2, x=0.5, y=0.0, yaw=0.0)
    moved = obj.with_pose(0.45, 0.1, 0.7)
    assert moved.content_digest == obj.content_digest is not None
    assert moved.x == 0.45 and moved.y == 0.1 and moved.yaw == 0.7 and moved.z is None
    assert obj.x == 0.5  # the original is untouched
    np.testing.assert_allclose(moved.o1, [math.cos(0.7), math.sin(0.7), 0.0], atol=1e-12)  # major axis = x
    assert object_geometry(moved.primitive()) is object_geometry(obj.primitive())
    # the same content built again (a new request) finds the same hull; other content does not
    again = mesh(V.copy(), F.copy(), 0.3, x=0.4)
    assert again.content_digest == obj.content_digest
    assert object_geometry(again.primitive()) is object_geometry(obj.primitive())
    other = mesh(V * 1.01, F, 0.2)
    assert other.content_digest != obj.content_digest
    assert object_geometry(other.primitive()) is not object_geometry(obj.primitive())
    with pytest.raises(InvalidInput) as info:
        obj.with_pose(float("nan"), 0.0)
    assert info.value.field == "object.pose.x"


def test_a_moved_mesh_plans_like_a_new_one() -> None:
    """Plans of a mesh moved with with_pose equal plans of the mesh built afresh at that pose."""
    V, F = _ellipsoid(14, (0.05, 0.035, 0.035))
    planner = Planner()
    base = mesh(V, F, 0.2)
    for x, y, yaw in ((0.5, 0.05, 0.3), (0.42, -0.12, -1.1)):
        for strategy in ("S", "C"):
            a = planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=base.with_pose(x, y, yaw), strategy=strategy))  # type: ignore[arg-type]
            b = planner.plan(
                PlanRequest(hand="pisa_iit_softhand", obj=mesh(V, F, 0.2, x=x, y=y, yaw=yaw), strategy=strategy)
            )  # type: ignore[arg-type]
            assert a.success and a.joint_positions == b.joint_positions and a.object == b.object
