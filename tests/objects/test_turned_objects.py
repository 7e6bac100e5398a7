"""Objects in full 6-DoF poses: a quaternion turns the object's frame, and the object becomes the mesh of its turned
shape. A quaternion about z is the same object as that yaw; a standing cylinder turned a quarter about x is a lying
one; a box on its edge is as tall as its diagonal says; the volume is kept for any rotation; bad input is named."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.errors import InvalidInput
from softsig_service.objects import object_from_json
from softsig_service.planning.planner import Planner
from softsig_service.planning.request import PlanRequest

BOX = {"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15}


def _about(axis: str, angle: float) -> dict[str, float]:
    q = {"x": 0.0, "y": 0.0, "z": 0.0, "w": math.cos(angle / 2)}
    q[axis] = math.sin(angle / 2)
    return q


def _volume(obj: object) -> float:
    V, F = obj.vertices, obj.faces  # type: ignore[attr-defined]
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def test_a_quaternion_about_z_is_the_yaw() -> None:
    yawed = object_from_json({**BOX, "pose": {"x": 0.5, "y": 0.05, "yaw": 0.4}})
    turned = object_from_json({**BOX, "pose": {"x": 0.5, "y": 0.05, "orientation": _about("z", 0.4)}})
    assert turned.kind == "mesh"
    assert (turned.extent_major, turned.extent_minor, turned.height) == pytest.approx(
        (yawed.extent_major, yawed.extent_minor, yawed.height), abs=1e-9
    )
    assert abs(abs(float(turned.o1 @ yawed.o1)) - 1.0) < 1e-9 and np.allclose(turned.center, yawed.center)
    planner = Planner()
    a = planner.plan(PlanRequest(hand="parallel_gripper", obj=yawed, strategy="S"))
    b = planner.plan(PlanRequest(hand="parallel_gripper", obj=turned, strategy="S"))
    assert a.success and b.success and np.allclose(a.grasp_pose[:3, 3], b.grasp_pose[:3, 3], atol=1e-6)


def test_a_standing_cylinder_turned_a_quarter_about_x_lies_along_y() -> None:
    spec = {"kind": "cylinder", "radius": 0.03, "length": 0.16, "orientation": "standing", "mass": 0.2}
    lying = object_from_json({**spec, "pose": {"x": 0.5, "y": 0.0, "orientation": _about("x", math.pi / 2)}})
    assert lying.extent_major == pytest.approx(0.16, abs=1e-9) and abs(abs(lying.o1[1]) - 1.0) < 1e-9
    assert 0.06 * math.cos(math.pi / 48) <= lying.extent_minor <= 0.06 + 1e-9  # 48 facets, inside the cylinder
    assert lying.center[2] == pytest.approx(lying.height / 2)  # resting on the table


def test_a_box_on_its_edge_is_as_tall_as_its_diagonal() -> None:
    edge = object_from_json({**BOX, "pose": {"x": 0.5, "y": 0.0, "orientation": _about("x", math.pi / 4)}})
    assert edge.height == pytest.approx((0.06 + 0.05) * math.sin(math.pi / 4), abs=1e-9)
    held = object_from_json({**BOX, "pose": {"x": 0.5, "y": 0.0, "z": 0.3, "orientation": _about("x", 0.3)}})
    assert held.center[2] == 0.3  # planned as given, above the table


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(min_value=-1.0, max_value=1.0), min_size=4, max_size=4).filter(
    lambda q: float(np.linalg.norm(q)) > 0.1))  # fmt: skip
def test_any_rotation_keeps_the_volume_and_rests_the_object_on_the_table(q: list[float]) -> None:
    x, y, z, w = np.asarray(q) / np.linalg.norm(q)
    turned = object_from_json({**BOX, "pose": {"orientation": {"x": x, "y": y, "z": z, "w": w}}})
    assert _volume(turned) == pytest.approx(0.16 * 0.06 * 0.05, rel=1e-9)
    assert turned.center[2] - turned.height / 2 == pytest.approx(0.0, abs=1e-12)
    assert math.sqrt(turned.extent_major**2 + turned.extent_minor**2 + turned.height**2) <= math.sqrt(
        0.16**2 + 0.06**2 + 0.05**2) * math.sqrt(3) + 1e-9  # fmt: skip


@pytest.mark.parametrize(
    ("pose", "field"),
    [
        ({"yaw": 0.3, "orientation": _about("x", 0.2)}, "object.pose.yaw"),
        ({"orientation": {"x": 0.5, "y": 0.0, "z": 0.0, "w": 0.5}}, "object.pose.orientation"),
    ],
)
def test_bad_orientations_are_named(pose: dict[str, object], field: str) -> None:
    with pytest.raises(InvalidInput) as info:
        object_from_json({**BOX, "pose": pose})
    assert info.value.field == field


def test_a_turned_shape_too_small_to_mesh_is_refused_not_a_crash() -> None:
    """A 0.1 mm cylinder turned by a quaternion collapses to no triangles: 422, not an IndexError (a 500)."""
    from softsig_service.errors import InvalidInput
    from softsig_service.objects import object_from_json

    spec = {"kind": "cylinder", "length": 0.0001, "radius": 0.0001, "mass": 0.0001, "orientation": "lying",
            "pose": {"x": 0.5, "y": 0.0, "z": 0.0, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}  # fmt: skip
    with pytest.raises(InvalidInput):
        object_from_json(spec)
