"""Minimum-volume enclosing ellipsoid: containment, exactness, equivariance, minimality, fallbacks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput
from softsig_service.geometry.ellipsoid import DEFAULT_TOL, Ellipsoid, mvee, mvee_batch
from softsig_service.geometry.quaternions import quat_to_matrix

FAST = settings(max_examples=40, deadline=None)

OCTAHEDRON = np.vstack([np.eye(3), -np.eye(3)])


def rotation(q: tuple[float, float, float, float]) -> NDArray[np.float64]:
    """Rotation matrix of the (not necessarily unit) quaternion q = (w, x, y, z)."""
    return quat_to_matrix(q)


quaternions = st.tuples(*[st.floats(-1.0, 1.0) for _ in range(4)]).filter(
    lambda q: math.sqrt(sum(v * v for v in q)) > 0.2
)
seeds = st.integers(0, 2**32 - 1)


def generic_points(seed: int, n: int) -> NDArray[np.float64]:
    """n Gaussian points, a hand-sized cloud [m] away from the origin."""
    rng = np.random.default_rng(seed)
    return np.array([0.02, -0.01, 0.12]) + rng.normal(scale=[0.05, 0.03, 0.02], size=(n, 3))


def relative_error(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# ------------------------------------------------------------------------------------------------ containment


@FAST
@given(
    grid=st.lists(st.tuples(*[st.integers(-50, 50)] * 3), min_size=4, max_size=10),
    scale=st.sampled_from([1e-3, 0.1, 1.0, 50.0]),
    offset=st.tuples(*[st.integers(-100, 100)] * 3),
)
def test_the_ellipsoid_contains_every_point(
    grid: list[tuple[int, int, int]], scale: float, offset: tuple[int, int, int]
) -> None:
    pts = (np.array(grid, dtype=float) / 50.0 + np.array(offset) / 10.0) * scale
    if np.all(pts == pts[0]):
        with pytest.raises(InvalidInput, match="coincide"):
            mvee(pts)
        return
    e = mvee(pts)
    assert e.converged
    assert e.gap <= DEFAULT_TOL
    level = e.level(pts)
    assert level.max() <= 1.0 + 1e-9
    if e.n_lifted == 0:  # rescaled so that the farthest point is on the boundary
        assert level.max() >= 1.0 - 1e-9
    assert np.all(e.semi_axes > 0)
    assert np.all(np.diff(e.semi_axes) <= 0)
    np.testing.assert_allclose(e.axes.T @ e.axes, np.eye(3), atol=1e-9)


@FAST
@given(seed=seeds, n=st.integers(5, 12))
def test_no_nearby_enclosing_ellipsoid_is_smaller(seed: int, n: int) -> None:
    """Minimality: perturb (c, A), enlarge it to enclose the points again: its volume is never smaller."""
    pts = generic_points(seed, n)
    e = mvee(pts)
    logdet = np.linalg.slogdet(e.shape)[1]  # volume ~ det(A)^(-1/2): larger log det = smaller ellipsoid
    rng = np.random.default_rng(seed + 1)
    for _ in range(20):
        s = rng.normal(size=(3, 3))
        shape = e.shape + 1e-2 * np.linalg.norm(e.shape) * (s + s.T) / 2
        if np.any(np.linalg.eigvalsh(shape) <= 0):
            continue
        center = e.center + 1e-2 * e.semi_axes.min() * rng.normal(size=3)
        x = pts - center
        shape = shape / np.einsum("ki,ij,kj->k", x, shape, x).max()
        # slack: E may exceed the optimum by the tolerance, log det by at most 3 ln(1 + 4/3 tol)
        assert np.linalg.slogdet(shape)[1] <= logdet + 1e-6


# -------------------------------------------------------------------------------------------------- exactness


@FAST
@given(
    q=quaternions,
    semi=st.tuples(*[st.floats(0.01, 1.0)] * 3),
    center=st.tuples(*[st.floats(-1.0, 1.0)] * 3),
    n_extra=st.integers(0, 10),
    seed=seeds,
)
def test_points_on_a_known_ellipsoid_give_it_back(
    q: tuple[float, float, float, float],
    semi: tuple[float, float, float],
    center: tuple[float, float, float],
    n_extra: int,
    seed: int,
) -> None:
    """The 6 axis end points (plus further surface points) pin the ellipsoid: the MVEE is that ellipsoid."""
    r = rotation(q)
    a = np.array(semi)
    c = np.array(center)
    dirs = np.random.default_rng(seed).normal(size=(n_extra, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    pts = c + (np.vstack([OCTAHEDRON, dirs]) * a) @ r.T
    e = mvee(pts)
    true_shape = (r / a**2) @ r.T
    assert e.converged
    np.testing.assert_allclose(e.center, c, atol=1e-7 * a.max())
    np.testing.assert_allclose(e.semi_axes, np.sort(a)[::-1], rtol=1e-6)
    assert relative_error(e.shape, true_shape) <= 1e-6
    assert e.volume == pytest.approx(4 / 3 * math.pi * np.prod(a), rel=1e-5)


def test_regular_tetrahedron_gives_its_circumscribed_sphere() -> None:
    pts = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    e = mvee(pts)
    assert e.iterations == 0  # d + 1 points: the uniform weights are optimal
    np.testing.assert_allclose(e.center, 0.0, atol=1e-12)
    np.testing.assert_allclose(e.semi_axes, math.sqrt(3.0), rtol=1e-12)


def test_half_width_is_the_support_function() -> None:
    r = rotation((0.9, 0.1, -0.3, 0.2))
    a = np.array([0.3, 0.2, 0.1])
    e = mvee(np.array([0.5, 0.0, -0.2]) + (OCTAHEDRON * a) @ r.T)
    for k in range(3):
        assert e.half_width(r[:, k]) == pytest.approx(a[k], rel=1e-7)
    v = np.array([1.0, 2.0, -2.0])
    expected = math.sqrt(float(np.sum(((r.T @ v) / 3.0) ** 2 * a**2)))
    assert e.half_width(v) == pytest.approx(expected, rel=1e-7)  # direction is normalised


# ----------------------------------------------------------------------------------------------- equivariance


@FAST
@given(seed=seeds, n=st.integers(4, 12), q1=quaternions, q2=quaternions, reflect=st.booleans())
def test_affine_equivariance(
    seed: int,
    n: int,
    q1: tuple[float, float, float, float],
    q2: tuple[float, float, float, float],
    reflect: bool,
) -> None:
    """E(M p + t) = M E(p) + t: centre M c + t, shape M^-T A M^-1."""
    rng = np.random.default_rng(seed)
    pts = generic_points(seed, n)
    stretch = np.diag(rng.uniform(0.3, 3.0, size=3) * np.array([-1.0 if reflect else 1.0, 1.0, 1.0]))
    m = rotation(q1) @ stretch @ rotation(q2)
    t = rng.uniform(-1.0, 1.0, size=3)
    e = mvee(pts)
    e2 = mvee(pts @ m.T + t)
    m_inv = np.linalg.inv(m)
    np.testing.assert_allclose(e2.center, m @ e.center + t, atol=1e-7)
    assert relative_error(e2.shape, m_inv.T @ e.shape @ m_inv) <= 1e-6
    assert e2.volume == pytest.approx(abs(np.linalg.det(m)) * e.volume, rel=1e-6)


# ---------------------------------------------------------------------------------------------------- batches


def test_batch_equals_one_at_a_time_including_a_lifted_frame() -> None:
    sets = np.stack([generic_points(s, 7) for s in range(5)])
    sets[2, :, 2] = 0.1  # coplanar frame inside the batch
    sets[4] = np.outer(np.linspace(-1, 1, 7), [0.1, 0.2, 0.0]) + 0.3  # collinear frame
    batch = mvee_batch(sets)
    assert len(batch) == 5
    assert list(batch.n_lifted) == [0, 0, 1, 0, 2]
    for i in range(5):
        single = mvee(sets[i])
        np.testing.assert_allclose(batch.center[i], single.center, rtol=1e-9, atol=1e-12)
        assert relative_error(batch.shape[i], single.shape) <= 1e-9
        assert batch[i].lifted_epsilon == single.lifted_epsilon


def test_iteration_cap_reports_non_convergence_but_still_encloses() -> None:
    pts = generic_points(7, 9)
    full = mvee(pts)
    assert full.converged and full.iterations >= 2
    capped = mvee(pts, max_iter=1)
    assert not capped.converged
    assert capped.iterations == 1
    assert capped.gap > DEFAULT_TOL
    assert capped.level(pts).max() <= 1.0 + 1e-12
    assert capped.volume >= full.volume


def test_six_points_converge_in_a_few_iterations() -> None:
    """With Newton steps 1e-7 is met in about 5-10 iterations on 6 points (plain Khachiyan: 10-500)."""
    batch = mvee_batch(np.stack([generic_points(s, 6) for s in range(200)]))
    assert batch.converged.all()
    assert batch.iterations.max() <= 15
    assert np.median(batch.iterations) <= 8


# ------------------------------------------------------------------------------------------------- degenerate


@pytest.mark.parametrize("aspect", [1e2, 1e4, 1e5])
def test_a_thin_ellipsoid_keeps_its_precision(aspect: float) -> None:
    """4 points (a simplex) all lie on their MVEE; a thin one must not lose that to round-off."""
    rng = np.random.default_rng(int(aspect))
    r = rotation((0.4, -0.2, 0.8, 0.3))
    pts = np.array([0.3, -0.1, 0.5]) + (rng.normal(size=(4, 3)) * [0.05, 0.03, 0.05 / aspect]) @ r.T
    e = mvee(pts)
    assert e.n_lifted == 0
    np.testing.assert_allclose(e.level(pts), 1.0, atol=1e-9)
    # affine invariance: vol(MVEE) / vol(simplex) is that of the regular tetrahedron in its sphere, 3 sqrt(3) pi / 2
    simplex_volume = abs(np.linalg.det(pts[1:] - pts[0])) / 6
    assert e.volume == pytest.approx(simplex_volume * 3 * math.sqrt(3) * math.pi / 2, rel=1e-9)


@pytest.mark.parametrize("lift", [1e-6, 1e-3])
def test_coplanar_points_are_lifted_and_reported(lift: float) -> None:
    r = rotation((0.7, 0.2, 0.5, -0.4))
    rng = np.random.default_rng(3)
    local = np.column_stack([rng.normal(scale=0.05, size=8), rng.normal(scale=0.02, size=8), np.zeros(8)])
    pts = np.array([0.01, 0.02, 0.1]) + local @ r.T
    normal = r[:, 2]
    e = mvee(pts, lift_epsilon=lift)
    rms_largest = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)[0] / math.sqrt(len(pts))
    assert e.n_lifted == 1
    assert e.lifted_epsilon == pytest.approx(lift * rms_largest, rel=1e-9)
    assert e.converged
    assert e.level(pts).max() <= 1.0 + 1e-9
    assert abs(e.axes[:, 2] @ normal) == pytest.approx(1.0, abs=1e-9)  # thinnest axis = the plane's normal
    assert 0.5 * e.lifted_epsilon <= e.semi_axes[2] <= 3.0 * e.lifted_epsilon
    assert e.semi_axes[1] > 100 * e.semi_axes[2]


def test_collinear_points_are_lifted_in_two_directions() -> None:
    line = np.array([1.0, 2.0, -2.0]) / 3.0
    pts = np.array([0.1, 0.0, 0.2]) + np.outer([-0.05, -0.01, 0.0, 0.02, 0.04, 0.05], line)
    e = mvee(pts)
    assert e.n_lifted == 2
    assert e.lifted_epsilon > 0
    assert abs(e.axes[:, 0] @ line) == pytest.approx(1.0, abs=1e-9)
    assert e.semi_axes[0] >= 0.05
    assert e.semi_axes[1] <= 3.0 * e.lifted_epsilon
    assert e.level(pts).max() <= 1.0 + 1e-9


def test_thin_but_not_flat_points_are_not_lifted() -> None:
    pts = generic_points(11, 8)
    pts[:, 2] = 0.1 + 1e-4 * (pts[:, 2] - pts[:, 2].mean())  # 1e-4 relative thickness > 1e-6
    e = mvee(pts)
    assert e.n_lifted == 0
    assert e.lifted_epsilon == 0.0
    assert e.converged
    assert e.level(pts).max() == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize(
    ("points", "kwargs", "field", "match"),
    [
        (np.zeros((3, 3)) + np.eye(3), {}, "points", "at least 4 points"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, np.nan]]), {}, "points[3][2]", "finite"),
        (np.ones((6, 3)) * 0.3, {}, "points", "coincide"),
        (np.ones(6), {}, "points", "shape"),
        (OCTAHEDRON, {"tol": 1e-5}, "tol", "tol must be"),
        (OCTAHEDRON, {"lift_epsilon": 0.0}, "lift_epsilon", "lift_epsilon must be"),
        (OCTAHEDRON, {"max_iter": -1}, "max_iter", "max_iter"),
    ],
)
def test_bad_input_raises_a_clear_error(points: object, kwargs: dict[str, float], field: str, match: str) -> None:
    with pytest.raises(InvalidInput, match=match) as info:
        mvee(points, **kwargs)  # type: ignore[arg-type]
    assert info.value.field == field


def test_json_form_lists_unit_axes() -> None:
    e = mvee(generic_points(5, 6))
    data = e.to_json_dict()
    assert set(data) == {"center", "semi_axes", "axes"}
    axes = np.array(data["axes"])
    np.testing.assert_allclose(np.linalg.norm(axes, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(axes, e.axes.T)
    assert isinstance(e, Ellipsoid)
