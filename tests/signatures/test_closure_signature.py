"""Closure signature (ellipsoid | pca | mesh): known closures, rigid-motion invariance, JSON, errors, plot."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput, InvalidTrajectory
from softsig_service.geometry.pca import orient_axes, principal_components
from softsig_service.geometry.transforms import quat_to_matrix
from softsig_service.hands.trajectory import ClosureTrajectory
from softsig_service.signatures.closure import (
    DISTINCTNESS_CAP,
    METHODS,
    ClosureSignature,
    compute_closure_signature,
    distinctness_ratio,
    ellipsoid_axis_series,
    ellipsoid_closure_signature,
    mesh_closure_signature,
    pca_closure_signature,
)
from softsig_service.signatures.plot import plot_closure_signature

FAST = settings(max_examples=30, deadline=None)
OCTAHEDRON = np.vstack([np.eye(3), -np.eye(3)])
SEMI_AXES = np.array([0.06, 0.04, 0.025])  # distinct, so E_0's axes are well defined [m]
HAND_CENTRE = np.array([0.0, 0.01, 0.09])  # [m]
NAMES = ("thumb", "index", "middle", "ring", "little", "wrist", "p6", "p7", "p8", "p9")


def rotation(q: tuple[float, float, float, float]) -> NDArray[np.float64]:
    """Rotation matrix of the (not necessarily unit) quaternion q = (w, x, y, z)."""
    return quat_to_matrix(q)


quaternions = st.tuples(*[st.floats(-1.0, 1.0) for _ in range(4)]).filter(
    lambda q: math.sqrt(sum(v * v for v in q)) > 0.2
)
seeds = st.integers(0, 2**32 - 1)


def open_hand(frame: NDArray[np.float64], n_inner: int = 2, seed: int = 0) -> NDArray[np.float64]:
    """Reference points of an open hand [m]: the 6 end points of an ellipsoid with semi-axes SEMI_AXES along
    the columns of ``frame`` (so E_0 is exactly that ellipsoid), plus ``n_inner`` points inside it."""
    rng = np.random.default_rng(seed)
    inner = rng.uniform(-0.3, 0.3, size=(n_inner, 3))
    return HAND_CENTRE + (np.vstack([OCTAHEDRON, inner]) * SEMI_AXES) @ frame.T


def close(
    p0: NDArray[np.float64],
    frame: NDArray[np.float64],
    factors: NDArray[np.float64],
    n_frames: int,
    *,
    shift: NDArray[np.float64] | None = None,
    noise: float = 0.0,
    seed: int = 0,
) -> NDArray[np.float64]:
    """A closure: at progress s in [0, 1] the points are scaled by 1 + (f_k - 1) s along frame[:, k] about
    HAND_CENTRE, shifted by s * shift, and perturbed by s * noise * N(0, 1) [m]."""
    rng = np.random.default_rng(seed)
    c = HAND_CENTRE
    shift = np.zeros(3) if shift is None else shift
    frames = []
    for s in np.linspace(0.0, 1.0, n_frames):
        local = (p0 - c) @ frame * (1.0 + (factors - 1.0) * s)
        frames.append(c + local @ frame.T + s * shift + s * noise * rng.normal(size=p0.shape))
    return np.stack(frames)


def trajectory(positions: NDArray[np.float64], surface: NDArray[np.float64] | None = None) -> ClosureTrajectory:
    t, n, _ = positions.shape
    return ClosureTrajectory(
        hand="test",
        times=np.linspace(0.0, 1.0, t),
        point_names=NAMES[:n],
        positions=positions,
        surface=surface,
    )


def same_line(u: ArrayLike, v: ArrayLike) -> float:
    """|cos| of the angle between two axes (1 = the same line)."""
    a, b = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    return float(abs(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b)))


def follows_sign_rule(v: NDArray[np.float64]) -> bool:
    """DESIGN §4: the first component of magnitude > 1e-9 (x, else y, else z) is positive."""
    significant = [c for c in v if abs(c) > 1e-9]
    return bool(significant) and significant[0] > 0


# --------------------------------------------------------------------------------------------- known closures


@FAST
@given(q=quaternions, k=st.integers(0, 2), squeeze=st.floats(0.3, 0.8), n_frames=st.integers(2, 30))
def test_a_squeeze_along_a_known_axis_gives_that_axis_for_all_methods(
    q: tuple[float, float, float, float], k: int, squeeze: float, n_frames: int
) -> None:
    frame = rotation(q)
    p0 = open_hand(frame)
    factors = np.ones(3)
    factors[k] = squeeze
    p = close(p0, frame, factors, n_frames)
    expected = frame[:, k]
    traj = trajectory(p)

    cs_e = compute_closure_signature(traj, "ellipsoid")
    assert same_line(cs_e.axis, expected) >= 1 - 1e-9
    assert cs_e.magnitude == pytest.approx(squeeze - 1.0, abs=1e-6)
    np.testing.assert_allclose(cs_e.deformation[1:], 0.0, atol=1e-6)
    assert cs_e.distinctness == DISTINCTNESS_CAP  # the other deltas are below the resolution, 1e-6
    np.testing.assert_allclose(cs_e.anchor, HAND_CENTRE, atol=1e-9)  # c_0, the centre of the end points

    cs_p = compute_closure_signature(traj, "pca")
    along = (p0 - HAND_CENTRE) @ expected  # signed distance of each point from the centre along the axis
    progress = np.linspace(0.0, 1.0, n_frames)[1:]
    rms = math.sqrt(np.mean(np.outer(progress * (1.0 - squeeze), along) ** 2))
    assert same_line(cs_p.axis, expected) >= 1 - 1e-9
    assert cs_p.magnitude == pytest.approx(rms, rel=1e-9)
    np.testing.assert_allclose(cs_p.deformation[1:], 0.0, atol=1e-9)
    assert cs_p.distinctness == DISTINCTNESS_CAP
    assert cs_p.extras["explained_variance_ratio"][0] == pytest.approx(1.0, abs=1e-12)

    cs_m = compute_closure_signature(traj, "mesh")
    assert same_line(cs_m.axis, expected) >= 1 - 1e-9
    assert cs_m.magnitude == pytest.approx(math.log(squeeze), abs=1e-9)
    np.testing.assert_allclose(cs_m.extras["stretches"], [squeeze, 1.0, 1.0], atol=1e-9)
    assert cs_m.extras["fit_residual_rms"] <= 1e-12
    assert cs_m.params["source"] == "reference_points"

    for cs in (cs_e, cs_p, cs_m):
        assert follows_sign_rule(cs.axis)
        assert all(follows_sign_rule(row) for row in cs.axes)
        np.testing.assert_array_equal(cs.axis, cs.axes[0])
        assert cs.magnitude == cs.deformation[0]


def test_a_closure_along_two_axes_reports_each_delta_and_the_distinctness() -> None:
    frame = rotation((0.8, -0.3, 0.4, 0.1))
    p0 = open_hand(frame)
    factors = np.array([1.05, 0.7, 0.9])
    p = close(p0, frame, factors, 40)

    cs = ellipsoid_closure_signature(p)
    np.testing.assert_allclose(cs.deformation, [-0.3, -0.1, 0.05], atol=1e-6)
    for row, k in zip(cs.axes, [1, 2, 0], strict=True):
        assert same_line(row, frame[:, k]) >= 1 - 1e-9
    assert cs.distinctness == pytest.approx(3.0, rel=1e-5)
    assert not cs.ambiguous
    np.testing.assert_allclose(cs.extras["half_width_initial"], SEMI_AXES[[1, 2, 0]], rtol=1e-6)
    np.testing.assert_allclose(cs.extras["half_width_final"], (SEMI_AXES * factors)[[1, 2, 0]], rtol=1e-6)
    assert cs.initial_ellipsoid is not None and cs.final_ellipsoid is not None
    np.testing.assert_allclose(cs.initial_ellipsoid.semi_axes, SEMI_AXES, rtol=1e-6)

    cs_m = mesh_closure_signature(p)
    np.testing.assert_allclose(cs_m.deformation, np.log([0.7, 0.9, 1.05]), atol=1e-9)
    assert cs_m.distinctness == pytest.approx(math.log(0.7) / math.log(0.9), rel=1e-9)


def test_equal_squeezes_are_flagged_ambiguous() -> None:
    frame = rotation((0.3, 0.2, -0.9, 0.1))
    p = close(open_hand(frame), frame, np.array([0.7, 0.7, 1.0]), 10)
    cs = ellipsoid_closure_signature(p)
    assert cs.distinctness == pytest.approx(1.0, abs=1e-5)
    assert cs.ambiguous
    assert cs.to_json_dict()["ambiguous"] is True


def test_centre_drift_and_the_per_frame_series() -> None:
    frame = rotation((0.9, 0.1, 0.2, -0.3))
    p0 = open_hand(frame)
    shift = np.array([0.004, -0.002, 0.01])
    factors = np.array([0.6, 0.85, 1.0])
    p = close(p0, frame, factors, 25, shift=shift)
    cs = ellipsoid_closure_signature(p)
    np.testing.assert_allclose(cs.extras["centre_drift"], cs.axes @ shift, atol=1e-8)

    series = ellipsoid_axis_series(p)
    progress = np.linspace(0.0, 1.0, 25)
    assert series.half_widths.shape == (25, 3)
    assert series.converged.all()
    np.testing.assert_allclose(series.half_widths[0], SEMI_AXES, rtol=1e-6)
    np.testing.assert_allclose(series.relative_change, np.outer(progress, factors - 1.0), atol=1e-6)
    np.testing.assert_allclose(series.centre_drift, np.outer(progress, series.axes @ shift), atol=1e-8)
    # the series' last row holds the signature's deltas (same axes, different order)
    for row, value in zip(cs.axes, cs.deformation, strict=True):
        k = int(np.argmax(np.abs(series.axes @ row)))
        assert series.relative_change[-1, k] == pytest.approx(value, abs=1e-7)


# ------------------------------------------------------------------------------------------------- invariance


@FAST
@given(
    q_hand=quaternions,
    q_move=quaternions,
    shift=st.tuples(*[st.floats(-0.5, 0.5)] * 3),
    order=st.permutations([0.6, 0.85, 1.0]),
    seed=seeds,
)
def test_a_rigid_motion_rotates_the_axis_and_keeps_magnitude_and_distinctness(
    q_hand: tuple[float, float, float, float],
    q_move: tuple[float, float, float, float],
    shift: tuple[float, float, float],
    order: list[float],
    seed: int,
) -> None:
    frame = rotation(q_hand)
    factors = np.array(order)
    p = close(open_hand(frame, n_inner=3, seed=seed), frame, factors, 12, noise=5e-4, seed=seed)
    rng = np.random.default_rng(seed)
    surface0 = HAND_CENTRE + rng.normal(scale=[0.05, 0.03, 0.02], size=(40, 3)) @ frame.T
    surface = close(surface0, frame, factors, 12, noise=5e-4, seed=seed + 1)
    r = rotation(q_move)
    t = np.array(shift)
    moved = trajectory(p @ r.T + t, surface @ r.T + t)
    base = trajectory(p, surface)
    for method in METHODS:
        cs = compute_closure_signature(base, method)
        cs2 = compute_closure_signature(moved, method)
        assert same_line(cs2.axis, r @ cs.axis) >= 1 - 1e-6, method
        assert cs2.magnitude == pytest.approx(cs.magnitude, rel=1e-6), method
        assert cs2.distinctness == pytest.approx(cs.distinctness, rel=1e-5), method
        np.testing.assert_allclose(cs2.deformation, cs.deformation, rtol=1e-5, atol=1e-9)
        np.testing.assert_allclose(cs2.anchor, r @ cs.anchor + t, atol=1e-9)
        for row, row2 in zip(cs.axes, cs2.axes, strict=True):
            assert same_line(row2, r @ row) >= 1 - 1e-6, method


# ------------------------------------------------------------------------------------------------ conventions


def test_sign_rule() -> None:
    np.testing.assert_array_equal(orient_axes([-0.6, 0.8, 0.0]), [0.6, -0.8, 0.0])
    np.testing.assert_array_equal(orient_axes([0.0, -1.0, 0.0]), [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(orient_axes([0.0, 0.0, -1.0]), [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(orient_axes([1e-12, -0.6, -0.8]), [-1e-12, 0.6, 0.8])  # |x| <= 1e-9: use y
    rows = orient_axes([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    np.testing.assert_array_equal(rows, [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert not np.signbit(rows).any()  # no -0.0 left behind


@pytest.mark.parametrize(("k", "expected"), [(0, [1.0, 0.0, 0.0]), (1, [0.0, 1.0, 0.0]), (2, [0.0, 0.0, 1.0])])
@pytest.mark.parametrize("method", METHODS)
def test_a_squeeze_along_a_hand_axis_gives_that_axis_with_positive_sign(
    method: str, k: int, expected: list[float]
) -> None:
    factors = np.ones(3)
    factors[k] = 0.5
    p = close(open_hand(np.eye(3)), np.eye(3), factors, 5)
    cs = compute_closure_signature(trajectory(p), method)  # type: ignore[arg-type]
    np.testing.assert_allclose(cs.axis, expected, atol=1e-9)


@pytest.mark.parametrize(
    ("values", "expected"),
    [
        ([0.0, 0.0, 0.0], 1.0),
        ([0.2, 0.0, 0.0], DISTINCTNESS_CAP),
        ([-2.0, 1.0, 0.5], 2.0),
        ([3.0, -3.0, 0.0], 1.0),
    ],
)
def test_distinctness_ratio(values: list[float], expected: float) -> None:
    assert distinctness_ratio(values) == expected


def test_distinctness_ignores_values_below_the_resolution() -> None:
    assert distinctness_ratio([3e-9, -1e-9, 0.0], resolution=1e-8) == 1.0
    assert distinctness_ratio([0.3, -1e-9, 0.0], resolution=1e-8) == DISTINCTNESS_CAP
    assert distinctness_ratio([0.3, -0.1, 0.0], resolution=1e-8) == pytest.approx(3.0)
    assert distinctness_ratio([3e-9, -1e-9, 0.0]) == pytest.approx(3.0)


@pytest.mark.parametrize("method", METHODS)
def test_a_hand_that_does_not_move_is_ambiguous(method: str) -> None:
    p0 = open_hand(rotation((0.3, 0.1, 0.2, 0.9)), n_inner=3)
    traj = trajectory(np.stack([p0, p0, p0]))
    cs = compute_closure_signature(traj, method)  # type: ignore[arg-type]
    assert abs(cs.magnitude) <= cs.extras["resolution"]
    assert cs.distinctness == 1.0
    assert cs.ambiguous


@pytest.mark.parametrize("method", METHODS)
def test_json_form(method: str) -> None:
    frame = rotation((0.5, 0.5, 0.1, -0.2))
    p = close(open_hand(frame), frame, np.array([0.6, 0.9, 1.0]), 8, noise=1e-4)
    cs = compute_closure_signature(trajectory(p), method)  # type: ignore[arg-type]
    data = json.loads(json.dumps(cs.to_json_dict(), allow_nan=False))
    keys = {
        "method",
        "frame_id",
        "axis",
        "anchor",
        "magnitude",
        "deformation",
        "axes",
        "distinctness",
        "ambiguous",
        "params",
        "extras",
    }
    if method == "ellipsoid":
        keys |= {"initial_ellipsoid", "final_ellipsoid"}
        for name in ("initial_ellipsoid", "final_ellipsoid"):
            assert set(data[name]) == {"center", "semi_axes", "axes"}
            np.testing.assert_allclose(np.linalg.norm(data[name]["axes"], axis=1), 1.0, atol=1e-12)
        assert set(data["params"]) == {"tol", "max_iter", "lift_epsilon"}
        assert data["extras"]["solver"]["initial"]["converged"] is True
    assert set(data) == keys
    assert data["method"] == method
    assert data["frame_id"] == "hand"
    axes = np.array(data["axes"])
    assert axes.shape == (3, 3)
    np.testing.assert_allclose(np.linalg.norm(axes, axis=1), 1.0, atol=1e-12)
    assert data["axis"] == data["axes"][0]
    assert data["magnitude"] == data["deformation"][0]
    assert data["extras"]["n_frames"] == 8 and data["extras"]["n_points"] == 8
    assert isinstance(cs, ClosureSignature)


# ---------------------------------------------------------------------------------------------------- methods


def test_principal_components_about_zero_and_about_the_mean() -> None:
    rng = np.random.default_rng(2)
    offset = np.array([0.0, 0.0, 1.0])
    spread = np.outer(rng.normal(size=200), [1.0, 0.0, 0.0]) * 0.1
    pts = offset + spread
    about_zero = principal_components(pts, about="zero")
    about_mean = principal_components(pts, about="mean")
    assert same_line(about_zero.directions[:, 0], offset) >= 1 - 1e-3
    assert same_line(about_mean.directions[:, 0], [1.0, 0.0, 0.0]) >= 1 - 1e-9
    np.testing.assert_allclose(about_mean.explained_variance_ratio, [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(about_mean.origin, pts.mean(axis=0))
    assert about_mean.variances[0] == pytest.approx(np.var(spread[:, 0]), rel=1e-9)
    assert about_zero.explained_variance_ratio.sum() == pytest.approx(1.0)
    with pytest.raises(InvalidInput) as info:
        principal_components(pts, about="median")  # type: ignore[arg-type]
    assert info.value.choices == ["mean", "zero"]


def test_pca_about_the_mean_is_a_parameter() -> None:
    frame = rotation((0.2, 0.9, -0.1, 0.3))
    p = close(open_hand(frame), frame, np.array([0.5, 1.0, 1.0]), 10, shift=np.array([0.0, 0.0, 0.02]))
    zero = pca_closure_signature(p)
    mean = compute_closure_signature(trajectory(p), "pca", pca_about="mean")
    assert zero.params == {"about": "zero"} and mean.params == {"about": "mean"}
    assert sum(mean.extras["explained_variance_ratio"]) == pytest.approx(1.0)
    assert mean.magnitude < zero.magnitude  # the common drift is removed about the mean


def test_mesh_uses_the_surface_when_the_trajectory_has_one() -> None:
    frame = rotation((0.6, 0.1, 0.7, 0.2))
    rng = np.random.default_rng(4)
    surface0 = rng.normal(scale=0.04, size=(60, 3))
    factors = np.array([1.0, 0.55, 1.0])
    surface = close(surface0, frame, factors, 6)
    p = close(open_hand(frame), frame, np.array([0.9, 1.0, 1.0]), 6)  # reference points tell another story
    cs = compute_closure_signature(trajectory(p, surface), "mesh")
    assert cs.params == {"source": "surface"}
    assert cs.extras["n_points"] == 60
    assert same_line(cs.axis, frame[:, 1]) >= 1 - 1e-9
    np.testing.assert_allclose(cs.anchor, surface0.mean(axis=0), atol=1e-12)
    assert cs.extras["det_F"] == pytest.approx(0.55, rel=1e-9)
    assert cs.extras["rotation_angle"] == pytest.approx(0.0, abs=1e-6)


def test_mesh_reports_the_rotation_and_the_fit_residual() -> None:
    rng = np.random.default_rng(5)
    x0 = rng.normal(scale=0.05, size=(30, 3))
    r = rotation((math.cos(0.2), 0.0, 0.0, math.sin(0.2)))  # 0.4 rad about z
    x1 = (x0 * [1.0, 1.0, 0.8]) @ r.T + 0.01 + 1e-3 * rng.normal(size=x0.shape)
    cs = mesh_closure_signature(np.stack([x0, x1]))
    assert cs.extras["rotation_angle"] == pytest.approx(0.4, abs=0.02)
    assert 5e-4 < cs.extras["fit_residual_rms"] < 2e-3
    assert same_line(cs.axis, [0.0, 0.0, 1.0]) >= 0.999


def test_a_coplanar_open_hand_is_lifted_and_reported() -> None:
    p0 = open_hand(np.eye(3))
    p0[:, 2] = 0.09  # every point at the palm's height: coplanar
    p = close(p0, np.eye(3), np.array([0.6, 1.0, 1.0]), 5)
    p[-1, :, 2] += np.linspace(-0.01, 0.01, p.shape[1])  # the closed hand is not flat
    cs = ellipsoid_closure_signature(p)
    assert cs.extras["lifted_epsilon"]["initial"] > 0.0
    assert cs.extras["lifted_epsilon"]["final"] == 0.0
    assert cs.initial_ellipsoid is not None and cs.initial_ellipsoid.n_lifted == 1


# ----------------------------------------------------------------------------------------------------- errors


def test_unknown_method() -> None:
    p = close(open_hand(np.eye(3)), np.eye(3), np.array([0.6, 1.0, 1.0]), 3)
    with pytest.raises(InvalidInput) as info:
        compute_closure_signature(trajectory(p), "voronoi")  # type: ignore[arg-type]
    assert info.value.field == "method"
    assert info.value.choices == ["ellipsoid", "mesh", "pca"]


@pytest.mark.parametrize("fn", [ellipsoid_closure_signature, pca_closure_signature, mesh_closure_signature])
def test_bad_positions_raise_invalid_trajectory(fn: object) -> None:
    p = close(open_hand(np.eye(3)), np.eye(3), np.array([0.6, 1.0, 1.0]), 3)
    with pytest.raises(InvalidTrajectory, match="at least 4 points"):
        fn(p[:, :3])  # type: ignore[operator]
    with pytest.raises(InvalidTrajectory, match="2 frames"):
        fn(p[:1])  # type: ignore[operator]
    with pytest.raises(InvalidTrajectory, match="shape"):
        fn(p[:, :, :2])  # type: ignore[operator]
    bad = p.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(InvalidTrajectory, match="finite") as info:
        fn(bad)  # type: ignore[operator]
    assert info.value.field is not None and info.value.field.endswith("[1][2]")


def test_mesh_needs_initial_points_that_span_3d() -> None:
    p = close(open_hand(np.eye(3)), np.eye(3), np.array([0.6, 1.0, 1.0]), 3)
    p[0, :, 2] = 0.1
    with pytest.raises(InvalidTrajectory, match="coplanar") as info:
        mesh_closure_signature(p, source="reference_points")
    assert info.value.field == "positions[0]"


# ------------------------------------------------------------------------------------------------------- plot


@pytest.mark.parametrize("method", ["ellipsoid", "pca"])
def test_plot_writes_an_image(tmp_path: Path, method: str) -> None:
    frame = rotation((0.9, 0.2, 0.1, 0.3))
    traj = trajectory(close(open_hand(frame), frame, np.array([0.6, 0.9, 1.0]), 10))
    cs = compute_closure_signature(traj, method)  # type: ignore[arg-type]
    out = plot_closure_signature(traj, cs, tmp_path / "cs.png")
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 20_000
    with pytest.raises(InvalidInput) as info:
        plot_closure_signature(traj, cs, tmp_path / "cs.bmp")
    assert info.value.field == "path"
