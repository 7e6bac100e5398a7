"""The conservative solid of a point cloud: exact for what a camera sees of a box, containing every kept point,
outward-facing, invariant under the table's rigid motions, deaf to an outlier, and refusing flat or bad clouds."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.errors import InvalidInput
from softsig_service.objects.cloud import MIN_THICKNESS, conservative_solid, statistical_outliers


def _box_top_and_front(sx: float, sy: float, sz: float, n: int = 3000, seed: int = 0) -> np.ndarray:
    """Points a camera in front of and above a box resting on the table (z = 0) sees: its whole top and its front
    face (y = -sy / 2), with the top's corners included."""
    rng = np.random.default_rng(seed)
    top = np.c_[rng.uniform(-sx / 2, sx / 2, n), rng.uniform(-sy / 2, sy / 2, n), np.full(n, sz)]
    front = np.c_[rng.uniform(-sx / 2, sx / 2, n), np.full(n, -sy / 2), rng.uniform(0, sz, n)]
    corners = np.array([[a * sx / 2, b * sy / 2, sz] for a in (-1, 1) for b in (-1, 1)])
    return np.vstack([top, front, corners])


def test_a_box_seen_from_the_front_and_above_is_the_box() -> None:
    sx, sy, sz = 0.16, 0.06, 0.05
    solid = conservative_solid(_box_top_and_front(sx, sy, sz), filter_outliers=False)
    assert solid.volume == pytest.approx(sx * sy * sz, rel=1e-9)
    assert solid.thickness == pytest.approx(min(sx, sy, sz), rel=1e-9)
    assert np.allclose(solid.vertices.min(axis=0), [-sx / 2, -sy / 2, 0.0])
    assert np.allclose(solid.vertices.max(axis=0), [sx / 2, sy / 2, sz])


def _inside(solid_v: np.ndarray, solid_f: np.ndarray, p: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    a, b, c = (solid_v[solid_f[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    return np.all(np.einsum("fj,pfj->pf", n, p[:, None, :] - a[None]) <= tol * np.linalg.norm(n, axis=1), axis=1)


@settings(max_examples=30, deadline=None)
@given(
    st.integers(min_value=0, max_value=10_000),
    st.floats(min_value=-0.5, max_value=0.5),
    st.floats(min_value=-0.5, max_value=0.5),
    st.floats(min_value=-math.pi, max_value=math.pi),
    st.floats(min_value=-0.2, max_value=0.9),
)
def test_the_solid_holds_every_point_faces_out_and_moves_with_the_table(
    seed: int, dx: float, dy: float, yaw: float, table: float
) -> None:
    rng = np.random.default_rng(seed)
    P = rng.normal(0.0, 0.03, (400, 3)) + np.array([0.0, 0.0, 0.08])
    P[:, 2] = np.abs(P[:, 2]) + 0.005
    base = conservative_solid(P, filter_outliers=False)
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    moved_points = P @ R.T + [dx, dy, table]
    moved = conservative_solid(moved_points, table_height=table, filter_outliers=False)
    assert moved.volume == pytest.approx(base.volume, rel=1e-9)
    assert np.all(_inside(moved.vertices, moved.faces, moved_points, tol=1e-7))
    feet = moved_points.copy()
    feet[:, 2] = table
    assert np.all(_inside(moved.vertices, moved.faces, feet, tol=1e-7))  # the unseen part below is inside too
    centre = moved.vertices.mean(axis=0)
    assert np.all(_inside(moved.vertices, moved.faces, centre[None], tol=-1e-12))  # normals point out
    assert moved.vertices[:, 2].min() == pytest.approx(table)


def test_an_outlier_is_dropped_and_the_solid_does_not_reach_it() -> None:
    P = _box_top_and_front(0.1, 0.06, 0.05)
    speck = np.array([[0.0, 0.3, 0.2]])  # a flying pixel 30 cm away
    solid = conservative_solid(np.vstack([P, speck]))
    assert solid.outliers >= 1
    assert solid.vertices[:, 1].max() < 0.031 and solid.vertices[:, 2].max() < 0.051
    assert not statistical_outliers(P).any() or statistical_outliers(P).sum() < 0.05 * len(P)


def test_points_below_the_table_are_lifted_onto_it() -> None:
    P = _box_top_and_front(0.1, 0.06, 0.05)
    P[:5, 2] = -0.004  # table noise
    solid = conservative_solid(P, filter_outliers=False)
    assert solid.lifted == 5 and solid.vertices[:, 2].min() == 0.0


@pytest.mark.parametrize(
    ("points", "field"),
    [
        (np.full((3, 3), 0.1), "object.points"),
        (np.c_[np.linspace(0, 0.1, 50), np.linspace(0, 0.1, 50), np.zeros(50)], "object.points"),  # on the table
        (np.c_[np.full(50, 0.5), np.linspace(0, 0.1, 50), np.linspace(0.01, 0.1, 50)], "object.points"),  # a line
        (np.vstack([_box_top_and_front(0.1, 0.06, 0.05), [[np.nan, 0, 0]]]), "object.points[6004]"),
    ],
)
def test_bad_clouds_are_refused_naming_the_field(points: np.ndarray, field: str) -> None:
    with pytest.raises(InvalidInput) as info:
        conservative_solid(points)
    assert info.value.field == field


def test_a_sheet_thinner_than_the_limit_is_flat() -> None:
    rng = np.random.default_rng(1)
    sheet = np.c_[rng.uniform(0, 0.2, 500), rng.uniform(0, 0.2, 500), rng.uniform(0, 0.5 * MIN_THICKNESS, 500)]
    with pytest.raises(InvalidInput, match="flat"):
        conservative_solid(sheet, filter_outliers=False)
    thick = sheet.copy()
    thick[:, 2] += MIN_THICKNESS
    assert conservative_solid(thick, filter_outliers=False).thickness >= MIN_THICKNESS
