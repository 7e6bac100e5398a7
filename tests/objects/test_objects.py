"""Objects on the table: resting heights, principal horizontal axes, JSON specs and their errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service import objects as O  # noqa: N812
from softsig_service.errors import InvalidInput
from softsig_service.geometry.transforms import apply, rot_z


def box_mesh(sx: float, sy: float, sz: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an axis-aligned box with one corner at the origin."""
    V = np.array([[x, y, z] for x in (0.0, sx) for y in (0.0, sy) for z in (0.0, sz)])
    F = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    )  # fmt: skip
    return V, F


def axis_close(a: np.ndarray, b: np.ndarray, tol: float = 1e-9) -> bool:
    """Axes a and b are parallel (sign-free)."""
    return bool(abs(abs(float(np.dot(a, b))) - 1.0) < tol)


# -- built-ins (docs/design.md §7) ---------------------------------------------------------------------------------


def test_builtin_box() -> None:
    o = O.builtin_object("box", x=0.4, y=-0.1, yaw=0.3)
    assert o.kind == "box" and o.dimensions == (0.16, 0.06, 0.05) and o.mass == 0.15
    assert np.allclose(o.center, [0.4, -0.1, 0.025])
    assert o.height == pytest.approx(0.05) and o.top_z == pytest.approx(0.05)
    assert np.allclose(o.o1, [math.cos(0.3), math.sin(0.3), 0.0])
    assert np.allclose(o.o2, [-math.sin(0.3), math.cos(0.3), 0.0])
    assert o.extent_major == pytest.approx(0.16) and o.extent_minor == pytest.approx(0.06)
    assert not o.footprint_isotropic
    prim = o.primitive()
    assert prim.kind == "box" and prim.size == pytest.approx((0.08, 0.03, 0.025))
    assert np.allclose(o.primitive_pose, o.pose)


def test_builtin_apple() -> None:
    o = O.builtin_object("apple")
    assert o.kind == "ellipsoid" and o.dimensions == (0.040, 0.040, 0.036) and o.mass == 0.18
    assert np.allclose(o.center, [O.DEFAULT_X, O.DEFAULT_Y, 0.036])
    assert o.footprint_isotropic and np.allclose(o.o1, [1.0, 0.0, 0.0])
    assert o.extent_major == pytest.approx(0.08) == o.extent_minor


def test_builtin_cylinder_lies_along_its_x() -> None:
    o = O.builtin_object("cylinder", yaw=-1.0, table_height=0.75)
    assert o.kind == "cylinder" and o.dimensions == (0.03, 0.16) and o.mass == 0.20 and not o.standing
    assert o.center[2] == pytest.approx(0.75 + 0.03)  # lying: centre at table_height + radius
    assert axis_close(o.o1, rot_z(-1.0) @ np.array([1.0, 0.0, 0.0]))
    assert o.extent_major == pytest.approx(0.16) and o.extent_minor == pytest.approx(0.06)
    prim = o.primitive()
    assert prim.kind == "cylinder" and prim.size == pytest.approx((0.03, 0.08))  # (radius, half-length)
    # the primitive's z (MuJoCo/coal cylinder axis) is the object's x in the world
    assert np.allclose(o.primitive_pose[:3, 2], o.o1, atol=1e-12)
    end = apply(o.primitive_pose, [0.0, 0.0, 0.08])
    assert np.allclose(end, o.center + 0.08 * o.o1)


def test_unknown_builtin_lists_the_choices() -> None:
    with pytest.raises(InvalidInput) as info:
        O.builtin_object("teapot")
    assert info.value.field == "object.name"
    assert info.value.choices == sorted(O.OBJECT_NAMES)
    assert "apple, banana, box, cylinder, mug" in str(info.value)


# -- other shapes ------------------------------------------------------------------------------------------


def test_box_major_axis_follows_the_longer_side() -> None:
    o = O.box((0.05, 0.2, 0.1), 1.0, yaw=0.2)
    assert axis_close(o.o1, rot_z(0.2) @ np.array([0.0, 1.0, 0.0]))
    assert np.allclose(np.cross(o.o1, o.o2), [0.0, 0.0, 1.0])
    assert o.extent_major == pytest.approx(0.2) and o.extent_minor == pytest.approx(0.05)
    assert O.box((0.1, 0.1, 0.3), 1.0).footprint_isotropic


def test_standing_cylinder_and_sphere() -> None:
    c = O.cylinder(0.04, 0.2, 0.3, standing=True, table_height=0.1)
    assert c.height == pytest.approx(0.2) and c.center[2] == pytest.approx(0.2)
    assert c.footprint_isotropic and c.extent_major == pytest.approx(0.08)
    assert np.allclose(c.primitive_pose[:3, 2], [0.0, 0.0, 1.0])
    s = O.sphere(0.05, 0.1)
    assert s.center[2] == pytest.approx(0.05) and s.footprint_isotropic
    assert s.primitive().size == (0.05,)
    e = O.ellipsoid((0.02, 0.05, 0.03), 0.1, yaw=0.5)
    assert axis_close(e.o1, rot_z(0.5) @ np.array([0.0, 1.0, 0.0]))
    assert e.center[2] == pytest.approx(0.03)


def test_mesh_footprint_pca() -> None:
    V, F = box_mesh(0.2, 0.05, 0.03)
    phi = 0.6
    V = (rot_z(phi) @ V.T).T + np.array([1.0, 2.0, 3.0])  # rotated in its own frame, anywhere
    m = O.mesh(V, F, 0.2, x=0.4, y=0.1, yaw=0.25, table_height=0.02)
    assert axis_close(m.o1, rot_z(phi + 0.25) @ np.array([1.0, 0.0, 0.0]), tol=1e-9)
    assert m.extent_major == pytest.approx(0.2) and m.extent_minor == pytest.approx(0.05)
    assert m.height == pytest.approx(0.03) and m.center[2] == pytest.approx(0.02 + 0.015)
    assert m.vertices is not None
    assert np.allclose(m.vertices.min(axis=0), -m.vertices.max(axis=0))  # centred on the bounding box
    prim = m.primitive()
    assert prim.kind == "mesh" and prim.vertices is not None and prim.faces is not None
    lowest = apply(m.primitive_pose, prim.vertices)[:, 2].min()
    assert lowest == pytest.approx(0.02)  # rests on the table


def test_mesh_pca_uses_the_footprint_area_not_the_vertex_density() -> None:
    """Many vertices along the short side must not turn the major axis."""
    V, F = box_mesh(0.2, 0.05, 0.03)
    # 200 vertices on the long faces' middle line: a PCA of the vertices would pick y
    extra = np.array([[0.1, y, 0.015] for y in (0.0, 0.05) for _ in range(100)])
    V2 = np.vstack([V, extra])
    m = O.mesh(V2, F, 0.2)
    assert axis_close(m.o1, np.array([1.0, 0.0, 0.0]))
    pts = V2[:, :2] - V2[:, :2].mean(axis=0)
    vertex_pca = np.linalg.eigh(pts.T @ pts)[1][:, 1]
    assert not axis_close(np.append(vertex_pca, 0.0), np.array([1.0, 0.0, 0.0]), tol=1e-3)


def test_polygon_moments_of_a_rectangle() -> None:
    poly = O.convex_hull_2d(np.array([[0, 0], [2, 0], [2, 1], [0, 1], [1, 0.5]], dtype=float))
    assert len(poly) == 4
    area, c, M = O.polygon_moments(poly)
    assert area == pytest.approx(2.0) and np.allclose(c, [1.0, 0.5])
    assert np.allclose(M, [[1 * 2**3 / 12, 0.0], [0.0, 2 * 1**3 / 12]])  # h b^3 / 12, b h^3 / 12


@settings(max_examples=60)
@given(
    st.sampled_from(["box", "cylinder", "ellipsoid", "mesh"]),
    st.tuples(*[st.floats(min_value=0.01, max_value=0.3)] * 3),
    st.floats(min_value=-2 * math.pi, max_value=2 * math.pi),
)
def test_axes_are_an_orthonormal_horizontal_pair(kind: str, dims: tuple[float, ...], yaw: float) -> None:
    if kind == "box":
        o = O.box(dims, 0.1, yaw=yaw)
    elif kind == "cylinder":
        o = O.cylinder(dims[0], dims[1], 0.1, yaw=yaw)
    elif kind == "ellipsoid":
        o = O.ellipsoid(dims, 0.1, yaw=yaw)
    else:
        o = O.mesh(*box_mesh(*dims), 0.1, yaw=yaw)
    for a in (o.o1, o.o2):
        assert a[2] == 0.0 and math.isclose(float(np.linalg.norm(a)), 1.0, rel_tol=1e-12)
    assert abs(float(np.dot(o.o1, o.o2))) < 1e-12
    assert np.allclose(np.cross(o.o1, o.o2), [0.0, 0.0, 1.0])
    assert o.extent_major >= o.extent_minor - 1e-12
    assert o.center[2] - o.height / 2 == pytest.approx(0.0, abs=1e-12)


# -- JSON --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "spec",
    [
        {"kind": "box", "size": [0.1, 0.2, 0.3], "mass": 0.5, "friction": 0.7, "pose": {"x": 0.3, "y": 0.1}},
        {"kind": "cylinder", "radius": 0.02, "length": 0.1, "mass": 0.1, "orientation": "standing"},
        {"kind": "cylinder", "radius": 0.02, "length": 0.1, "mass": 0.1, "pose": {"yaw": 1.0, "z": 0.5}},
        {"kind": "sphere", "radius": 0.03, "mass": 0.1, "name": "ball"},
        {"kind": "ellipsoid", "radii": [0.03, 0.02, 0.01], "mass": 0.1},
        {"kind": "mesh", "vertices": box_mesh(0.1, 0.05, 0.02)[0].tolist(),
         "faces": box_mesh(0.1, 0.05, 0.02)[1].tolist(), "mass": 0.1},
    ],
)  # fmt: skip
def test_json_round_trip(spec: dict) -> None:
    o = O.object_from_json(spec, table_height=0.1)
    back = O.object_from_json(o.to_json(), table_height=0.1)
    assert back.kind == o.kind and back.dimensions == o.dimensions and back.standing == o.standing
    assert back.mass == o.mass and back.friction == o.friction
    assert np.allclose(back.pose, o.pose) and np.allclose(back.o1, o.o1)
    assert o.friction == spec.get("friction", O.DEFAULT_FRICTION)


def test_json_builtin_with_overrides() -> None:
    o = O.object_from_json({"kind": "builtin", "name": "apple", "mass": 0.2, "pose": {"x": 0.6, "yaw": 0.1}})
    assert o.kind == "ellipsoid" and o.mass == 0.2 and o.x == 0.6 and o.yaw == 0.1 and o.name == "apple"


@pytest.mark.parametrize(
    ("spec", "field"),
    [
        ({"kind": "box", "size": [0.1, 0.0, 0.1], "mass": 1}, "object.size[1]"),
        ({"kind": "box", "size": [0.1, -0.1, 0.1], "mass": 1}, "object.size[1]"),
        ({"kind": "box", "size": [0.1, math.nan, 0.1], "mass": 1}, "object.size[1]"),
        ({"kind": "box", "size": [0.1, 0.1, math.inf], "mass": 1}, "object.size[2]"),
        ({"kind": "box", "size": [0.1, 0.1], "mass": 1}, "object.size[2]"),  # the missing third side
        ({"kind": "box", "size": "big", "mass": 1}, "object.size"),
        ({"kind": "box", "size": [0.1, 0.1, 0.1]}, "object.mass"),
        ({"kind": "box", "size": [0.1, 0.1, 0.1], "mass": True}, "object.mass"),
        ({"kind": "box", "size": [0.1, 0.1, 0.1], "mass": 1, "friction": 0}, "object.friction"),
        ({"kind": "box", "size": [0.1, 0.1, 0.1], "mass": 1, "colour": "red"}, "object.colour"),
        ({"kind": "box", "size": [0.1, 0.1, 0.1], "mass": 1, "pose": {"x": math.nan}}, "object.pose.x"),
        ({"kind": "box", "size": [0.1, 0.1, 0.1], "mass": 1, "pose": {"roll": 1}}, "object.pose.roll"),
        ({"kind": "box", "size": [0.1, 0.1, 0.1], "mass": "0.5"}, "object.mass"),  # strings are not numbers
        ({"kind": "box", "size": [0.1, 0.1, 0.1], "mass": 1, "friction": False}, "object.friction"),
        ({"kind": "box", "size": [0.1, 0.1, 9.0], "mass": 1}, "object.size[2]"),  # the schema's range (<= 5 m)
        ({"kind": "box", "size": [0.1, 0.1, 0.1], "mass": 5e3}, "object.mass"),
        ({"kind": "box", "size": [0.1, 0.1, 0.1], "mass": 1, "pose": {"z": 0.02}}, "object.pose.z"),
        ({"kind": "sphere", "mass": 1}, "object.radius"),
        ({"kind": "cylinder", "radius": 0.1, "length": 0.1, "mass": 1, "orientation": "up"},
         "object.orientation"),
        ({"kind": "ellipsoid", "radii": [0.1, 0.1, 0.0], "mass": 1}, "object.radii[2]"),
        ({"kind": "cone", "mass": 1}, "object.kind"),
        ({"kind": "builtin", "name": "pear"}, "object.name"),
        ({"kind": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]],
          "faces": [[0, 1, 2], [1, 3, 2], [0, 2, 3], [0, 1, 3]], "mass": 1}, "object.vertices"),
        ({"kind": "mesh", "vertices": box_mesh(0.1, 0.1, 0.1)[0].tolist(),
          "faces": [[0, 1, 99]] * 4, "mass": 1}, "object.faces"),
    ],
)  # fmt: skip
def test_bad_json_names_the_field(spec: dict, field: str) -> None:
    with pytest.raises(InvalidInput) as info:
        O.object_from_json(spec)
    assert info.value.field == field, info.value


def test_unknown_kind_lists_the_choices() -> None:
    with pytest.raises(InvalidInput) as info:
        O.object_from_json({"kind": "cone"})
    assert info.value.choices == sorted(
        ["box", "builtin", "cylinder", "ellipsoid", "mesh", "points", "sphere", "stored", "tabletop"]
    )


def test_below_the_table_is_rejected_above_is_allowed() -> None:
    with pytest.raises(InvalidInput, match="below the table"):
        O.box((0.1, 0.1, 0.1), 1.0, table_height=0.5, z=0.52)
    held = O.box((0.1, 0.1, 0.1), 1.0, table_height=0.5, z=0.7)
    assert held.center[2] == 0.7
    assert held.with_pose(0.3, 0.2, 1.0).center[2] == pytest.approx(0.55)  # back on the table


def test_direct_construction_is_validated() -> None:
    with pytest.raises(InvalidInput):
        O.TableObject("box", (0.1, 0.1, 0.1), -1.0)
    with pytest.raises(InvalidInput):
        O.TableObject("sphere", (0.1,), 1.0, standing=True)
    with pytest.raises(InvalidInput):
        O.TableObject("torus", (0.1,), 1.0)  # type: ignore[arg-type]
