"""Closure signature (ellipsoid | pca | mesh): known closures, the ellipsoid's absolute and relative criteria,
rigid-motion invariance, JSON, errors, plot."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput, InvalidTrajectory
from softsig_service.experiments.closure_plot import magnitude_label, plot_closure_signature
from softsig_service.geometry.pca import orient_axes, principal_components
from softsig_service.geometry.quaternions import quat_to_matrix
from softsig_service.hands.trajectory import ClosureTrajectory
from softsig_service.signatures.closure import (
    compute_closure_signature,
    distinctness_ratio,
    ellipsoid_axis_series,
    ellipsoid_closure_signature,
    mesh_closure_signature,
    pca_closure_signature,
)
from softsig_service.signatures.closure_types import (
    CRITERIA,
    DISTINCTNESS_CAP,
    ELLIPSOID_RESOLUTION_FACTOR,
    METHODS,
    ClosureSignature,
)

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


def open_hand(
    frame: NDArray[np.float64], n_inner: int = 2, seed: int = 0, semi_axes: ArrayLike = SEMI_AXES
) -> NDArray[np.float64]:
    """Reference points of an open hand [m]: the 6 end points of an ellipsoid with semi-axes ``semi_axes`` [m]
    along the columns of ``frame`` (so E_0 is exactly that ellipsoid), plus ``n_inner`` points inside it."""
    rng = np.random.default_rng(seed)
    inner = rng.uniform(-0.3, 0.3, size=(n_inner, 3))
    return HAND_CENTRE + (np.vstack([OCTAHEDRON, inner]) * np.asarray(semi_axes)) @ frame.T


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
    """docs/design.md: the largest component is positive; among components within 1e-6 (relative) of the
    largest, the first decides."""
    mags = np.abs(v)
    first = next(i for i, m in enumerate(mags) if m >= mags.max() * (1 - 1e-6))
    return bool(mags.max() > 0) and v[first] > 0


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
    assert cs_e.magnitude == pytest.approx((squeeze - 1.0) * SEMI_AXES[k], abs=1e-8)  # [m]
    np.testing.assert_allclose(cs_e.deformation[1:], 0.0, atol=1e-8)
    # the other deltas are below the resolution, 10 x tol x the largest semi-axis = 6e-8 m
    assert cs_e.extras["resolution"] == pytest.approx(ELLIPSOID_RESOLUTION_FACTOR * 1e-7 * SEMI_AXES[0], rel=1e-6)
    assert cs_e.distinctness == DISTINCTNESS_CAP
    np.testing.assert_allclose(cs_e.anchor, HAND_CENTRE, atol=1e-9)  # c_0, the centre of the end points
    cs_r = compute_closure_signature(traj, "ellipsoid", criterion="relative")
    assert same_line(cs_r.axis, expected) >= 1 - 1e-9
    assert cs_r.magnitude == pytest.approx(squeeze - 1.0, abs=1e-6)
    np.testing.assert_allclose(cs_r.deformation[1:], 0.0, atol=1e-6)
    assert cs_r.distinctness == DISTINCTNESS_CAP  # below the relative resolution, 10 x tol = 1e-6

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

    for cs in (cs_e, cs_r, cs_p, cs_m):
        assert follows_sign_rule(cs.axis)
        assert all(follows_sign_rule(row) for row in cs.axes)
        np.testing.assert_array_equal(cs.axis, cs.axes[0])
        assert cs.magnitude == cs.deformation[0]


def test_a_closure_along_two_axes_reports_each_delta_and_the_distinctness() -> None:
    frame = rotation((0.8, -0.3, 0.4, 0.1))
    p0 = open_hand(frame)
    factors = np.array([1.05, 0.7, 0.9])
    p = close(p0, frame, factors, 40)
    # half-widths 60, 40, 25 mm -> 63, 28, 22.5 mm: changes +3, -12, -2.5 mm, or +5 %, -30 %, -10 %

    cs = ellipsoid_closure_signature(p)
    assert cs.params["criterion"] == "absolute" and cs.extras["magnitude_unit"] == "m"
    np.testing.assert_allclose(cs.deformation, [-0.012, 0.003, -0.0025], atol=1e-8)
    for row, k in zip(cs.axes, [1, 0, 2], strict=True):
        assert same_line(row, frame[:, k]) >= 1 - 1e-9
    assert cs.distinctness == pytest.approx(4.0, rel=1e-5)
    assert not cs.ambiguous
    np.testing.assert_allclose(cs.extras["absolute_change"], cs.deformation, rtol=1e-12)
    np.testing.assert_allclose(cs.extras["relative_change"], [-0.3, 0.05, -0.1], atol=1e-6)
    np.testing.assert_allclose(cs.extras["half_width_initial"], SEMI_AXES[[1, 0, 2]], rtol=1e-6)
    np.testing.assert_allclose(cs.extras["half_width_final"], (SEMI_AXES * factors)[[1, 0, 2]], rtol=1e-6)
    assert cs.initial_ellipsoid is not None and cs.final_ellipsoid is not None
    np.testing.assert_allclose(cs.initial_ellipsoid.semi_axes, SEMI_AXES, rtol=1e-6)
    np.testing.assert_allclose(np.sort(cs.final_ellipsoid.semi_axes), np.sort(SEMI_AXES * factors), rtol=1e-6)

    rel = ellipsoid_closure_signature(p, criterion="relative")
    assert rel.params["criterion"] == "relative" and rel.extras["magnitude_unit"] == "1"
    np.testing.assert_allclose(rel.deformation, [-0.3, -0.1, 0.05], atol=1e-6)
    for row, k in zip(rel.axes, [1, 2, 0], strict=True):
        assert same_line(row, frame[:, k]) >= 1 - 1e-9
    assert rel.distinctness == pytest.approx(3.0, rel=1e-5)
    np.testing.assert_allclose(rel.extras["relative_change"], rel.deformation, rtol=1e-12)
    np.testing.assert_allclose(rel.extras["absolute_change"], [-0.012, -0.0025, 0.003], atol=1e-8)

    cs_m = mesh_closure_signature(p)
    np.testing.assert_allclose(cs_m.deformation, np.log([0.7, 0.9, 1.05]), atol=1e-9)
    assert cs_m.distinctness == pytest.approx(math.log(0.7) / math.log(0.9), rel=1e-9)


def test_equal_squeezes_are_flagged_ambiguous() -> None:
    frame = rotation((0.3, 0.2, -0.9, 0.1))
    # 60 -> 48 mm and 40 -> 28 mm: the same absolute change (-12 mm), relative changes -20 % and -30 %
    p = close(open_hand(frame), frame, np.array([0.8, 0.7, 1.0]), 10)
    cs = ellipsoid_closure_signature(p)
    assert cs.distinctness == pytest.approx(1.0, abs=1e-5)
    assert cs.ambiguous
    assert cs.to_json_dict()["ambiguous"] is True
    assert ellipsoid_closure_signature(p, criterion="relative").distinctness == pytest.approx(1.5, rel=1e-5)
    # equal relative squeezes: ambiguous by the relative criterion, not by the absolute one
    p = close(open_hand(frame), frame, np.array([0.7, 0.7, 1.0]), 10)
    rel = ellipsoid_closure_signature(p, criterion="relative")
    assert rel.distinctness == pytest.approx(1.0, abs=1e-5)
    assert rel.ambiguous
    assert ellipsoid_closure_signature(p).distinctness == pytest.approx(1.5, rel=1e-5)


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
    np.testing.assert_allclose(series.absolute_change, np.outer(progress, SEMI_AXES * (factors - 1.0)), atol=1e-8)
    np.testing.assert_allclose(series.centre_drift, np.outer(progress, series.axes @ shift), atol=1e-8)
    # the series' last row holds the signature's deltas (same axes, different order), for either criterion
    rel = ellipsoid_closure_signature(p, criterion="relative")
    for sig, change in ((cs, series.absolute_change), (rel, series.relative_change)):
        for row, value in zip(sig.axes, sig.deformation, strict=True):
            k = int(np.argmax(np.abs(series.axes @ row)))
            assert change[-1, k] == pytest.approx(value, abs=1e-9)


# ---------------------------------------------------------------------------------- absolute vs relative delta


@pytest.mark.parametrize("q", [(1.0, 0.0, 0.0, 0.0), (0.7, 0.2, -0.4, 0.5)])
def test_a_thin_axis_that_grows_a_little_wins_only_the_relative_criterion(q: tuple[float, float, float, float]) -> None:
    # a flat open hand: half-widths 60, 30 and 4 mm along the columns of frame (the last one the palm normal);
    # closing, the long axis grows 60 -> 80 mm (+20 mm, +33 %), the middle one shrinks 30 -> 27 mm (-3 mm,
    # -10 %), the thin one grows 4 -> 9 mm (+5 mm, +125 %)
    frame = rotation(q)
    initial = np.array([0.060, 0.030, 0.004])
    final = np.array([0.080, 0.027, 0.009])
    p = close(open_hand(frame, n_inner=4, semi_axes=initial), frame, final / initial, 15)

    absolute = ellipsoid_closure_signature(p)
    assert absolute.params["criterion"] == "absolute" and absolute.extras["magnitude_unit"] == "m"
    assert same_line(absolute.axis, frame[:, 0]) >= 1 - 1e-9  # the long axis
    assert absolute.magnitude == pytest.approx(0.020, abs=1e-8)  # [m]
    np.testing.assert_allclose(absolute.deformation, [0.020, 0.005, -0.003], atol=1e-8)
    assert absolute.distinctness == pytest.approx(4.0, rel=1e-5)
    np.testing.assert_allclose(absolute.extras["relative_change"], [1 / 3, 1.25, -0.1], atol=1e-6)
    assert absolute.extras["resolution"] == pytest.approx(10 * 1e-7 * 0.080, rel=1e-6)  # E_T's largest [m]

    relative = ellipsoid_closure_signature(p, criterion="relative")
    assert relative.params["criterion"] == "relative" and relative.extras["magnitude_unit"] == "1"
    assert same_line(relative.axis, frame[:, 2]) >= 1 - 1e-9  # the thin palm normal
    assert relative.magnitude == pytest.approx(1.25, abs=1e-6)
    np.testing.assert_allclose(relative.deformation, [1.25, 1 / 3, -0.1], atol=1e-6)
    assert relative.distinctness == pytest.approx(3.75, rel=1e-5)
    np.testing.assert_allclose(relative.extras["absolute_change"], [0.005, 0.020, -0.003], atol=1e-8)
    assert relative.extras["resolution"] == pytest.approx(1e-6)

    for cs in (absolute, relative):
        assert follows_sign_rule(cs.axis)
        np.testing.assert_allclose(cs.anchor, HAND_CENTRE, atol=1e-9)
        assert cs.initial_ellipsoid is not None and cs.final_ellipsoid is not None
        np.testing.assert_allclose(cs.initial_ellipsoid.semi_axes, initial, rtol=1e-6)
        np.testing.assert_allclose(cs.final_ellipsoid.semi_axes, final, rtol=1e-6)
        np.testing.assert_allclose(
            cs.extras["absolute_change"],
            np.asarray(cs.extras["half_width_final"]) - cs.extras["half_width_initial"],
            rtol=1e-12,
        )
        # the same ellipsoids and the same per-axis changes, only elected differently
        assert cs.initial_ellipsoid.to_json_dict() == absolute.initial_ellipsoid.to_json_dict()  # type: ignore[union-attr]


def test_a_coplanar_open_hand_gets_an_in_plane_axis_by_the_absolute_criterion() -> None:
    # a flat open hand (lifted by the MVEE's fallback) squeezed along x; closed, it is 2 cm thick along z
    p0 = open_hand(np.eye(3))
    p0[:, 2] = 0.09
    p = close(p0, np.eye(3), np.array([0.6, 1.0, 1.0]), 5)
    p[-1, :, 2] += np.linspace(-0.01, 0.01, p.shape[1])
    absolute = ellipsoid_closure_signature(p)
    relative = ellipsoid_closure_signature(p, criterion="relative")
    assert absolute.extras["lifted_epsilon"]["initial"] > 0.0
    np.testing.assert_allclose(absolute.axis, [1.0, 0.0, 0.0], atol=1e-6)
    # the flat MVEE is the plane's minimum ellipse scaled by sqrt(3/2): a half-width of 60 mm x 1.22 along x
    assert absolute.extras["half_width_initial"][0] == pytest.approx(0.06 * math.sqrt(1.5), rel=1e-6)
    assert absolute.magnitude == absolute.extras["half_width_final"][0] - absolute.extras["half_width_initial"][0]
    assert -0.06 < absolute.magnitude < -0.02  # [m]
    # the relative change of the lifted normal is of order 1 / lift_epsilon, but that axis exists only by the
    # lift: it is listed last and never elected, by either criterion
    np.testing.assert_allclose(relative.axis, [1.0, 0.0, 0.0], atol=1e-6)
    ex = relative.extras
    assert relative.magnitude == pytest.approx(ex["half_width_final"][0] / ex["half_width_initial"][0] - 1.0)
    assert -0.6 < relative.magnitude < -0.3
    for cs in (absolute, relative):
        assert cs.extras["lifted_axes"] == [2]
        np.testing.assert_allclose(np.abs(cs.axes[2]), [0.0, 0.0, 1.0], atol=1e-6)
        assert any("lifting" in w for w in cs.extras["warnings"])
    assert abs(relative.extras["relative_change"][2]) > 1e3
    lifted_z = relative.extras["half_width_initial"][2]
    assert relative.extras["absolute_change"][2] == pytest.approx(relative.deformation[2] * lifted_z, rel=1e-9)


@FAST
@given(
    q_hand=quaternions,
    q_move=quaternions,
    shift=st.tuples(*[st.floats(-0.5, 0.5)] * 3),
    thin=st.floats(0.002, 0.02),
    factors=st.tuples(*[st.floats(0.4, 2.5)] * 3),
    seed=seeds,
)
def test_the_absolute_delta_is_invariant_under_rigid_motions_and_is_the_relative_one_times_a0(
    q_hand: tuple[float, float, float, float],
    q_move: tuple[float, float, float, float],
    shift: tuple[float, float, float],
    thin: float,
    factors: tuple[float, float, float],
    seed: int,
) -> None:
    frame = rotation(q_hand)
    semi = np.array([0.07, 0.035, thin])
    p = close(open_hand(frame, n_inner=4, seed=seed, semi_axes=semi), frame, np.array(factors), 6, noise=2e-4,
              seed=seed)  # fmt: skip
    r = rotation(q_move)
    t = np.array(shift)
    moved = p @ r.T + t

    cs = ellipsoid_closure_signature(p)
    cs2 = ellipsoid_closure_signature(moved)
    mags = np.sort(np.abs(cs.deformation))
    assume(mags[2] - mags[1] > 1e-5 and mags[1] - mags[0] > 1e-5)  # no near-ties: the axis order is defined
    np.testing.assert_allclose(cs2.deformation, cs.deformation, rtol=1e-6, atol=1e-9)  # [m]
    assert cs2.magnitude == pytest.approx(cs.magnitude, rel=1e-6)
    assert cs2.distinctness == pytest.approx(cs.distinctness, rel=1e-5)
    assert same_line(cs2.axis, r @ cs.axis) >= 1 - 1e-6  # the CS rotates with the input
    for row, row2 in zip(cs.axes, cs2.axes, strict=True):
        assert same_line(row2, r @ row) >= 1 - 1e-6
    np.testing.assert_allclose(cs2.anchor, r @ cs.anchor + t, atol=1e-9)
    np.testing.assert_allclose(cs2.extras["absolute_change"], cs.extras["absolute_change"], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(cs2.extras["relative_change"], cs.extras["relative_change"], rtol=1e-6, atol=1e-9)

    # absolute delta = relative delta x a_k(0), axis by axis, between the two criteria's signatures
    rel = ellipsoid_closure_signature(p, criterion="relative")
    a0 = np.asarray(rel.extras["half_width_initial"])
    for row, value in zip(cs.axes, cs.deformation, strict=True):
        j = int(np.argmax(np.abs(rel.axes @ row)))
        assert same_line(rel.axes[j], row) >= 1 - 1e-12
        assert value == pytest.approx(rel.deformation[j] * a0[j], rel=1e-12, abs=1e-15)
    np.testing.assert_allclose(
        cs.extras["absolute_change"], np.asarray(cs.extras["relative_change"]) * cs.extras["half_width_initial"],
        rtol=1e-12, atol=1e-15,
    )  # fmt: skip
    assert rel.initial_ellipsoid is not None and cs.initial_ellipsoid is not None
    np.testing.assert_array_equal(rel.initial_ellipsoid.semi_axes, cs.initial_ellipsoid.semi_axes)


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
    np.testing.assert_array_equal(orient_axes([0.6, -0.8, 0.0]), [-0.6, 0.8, 0.0])  # the largest (y) positive
    np.testing.assert_array_equal(orient_axes([0.8, -0.6, 0.0]), [0.8, -0.6, 0.0])
    np.testing.assert_array_equal(orient_axes([0.0, -1.0, 0.0]), [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(orient_axes([0.0, 0.0, -1.0]), [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(orient_axes([1e-12, -0.6, -0.8]), [-1e-12, 0.6, 0.8])
    np.testing.assert_array_equal(orient_axes([-1e-3, 0.6, -0.8]), [1e-3, -0.6, 0.8])  # z decides, not x
    tie = np.array([-1.0, 1.0, 0.0]) / math.sqrt(2.0)
    np.testing.assert_array_equal(orient_axes(tie), -tie)  # a tie: the first of the equal components decides
    rows = orient_axes([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    np.testing.assert_array_equal(rows, [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert not np.signbit(rows).any()  # no -0.0 left behind


@FAST
@given(v=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3), q=quaternions)
def test_the_sign_rule_is_an_axis_rule_and_stable_under_tiny_rotations(
    v: list[float], q: tuple[float, float, float, float]
) -> None:
    u = np.asarray(v)
    assume(np.linalg.norm(u) > 1e-3)
    u = u / np.linalg.norm(u)
    a = orient_axes(u)
    np.testing.assert_array_equal(a, orient_axes(-u))  # an axis: its sign carries no meaning
    assert a[int(np.argmax(np.abs(a)))] > 0.0
    # a rotation by 1e-7 rad about any axis keeps the sign unless u sits within 1e-6 of a tie
    mags = np.sort(np.abs(u))[::-1]
    assume(mags[0] - mags[1] > 1e-5)
    w = rotation(q)[:, 0] * 1e-7
    R = np.eye(3) + np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    assert float(orient_axes(R @ u) @ a) > 0.0


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
        assert set(data["params"]) == {"tol", "max_iter", "lift_epsilon", "criterion"}
        assert data["params"]["criterion"] == "absolute" and data["extras"]["magnitude_unit"] == "m"
        assert data["extras"]["solver"]["initial"]["converged"] is True
        for key in ("absolute_change", "relative_change", "half_width_initial", "half_width_final", "centre_drift"):
            assert len(data["extras"][key]) == 3, key
        assert data["extras"]["absolute_change"] == data["deformation"]
    else:
        assert "criterion" not in data["params"]
        assert "absolute_change" not in data["extras"]
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
    assert cs.extras["lifted_axes"] == [2] and abs(cs.axis[2]) < 1e-6  # the CS lies in the open hand's plane


def test_nearly_equal_semi_axes_of_the_open_hand_are_reported() -> None:
    # six points on a circle of radius 5 cm (round in x, y) and two on the axis: E_0 has two equal semi-axes
    ang = np.linspace(0.0, 2.0 * math.pi, 6, endpoint=False)
    ring = np.c_[0.05 * np.cos(ang), 0.05 * np.sin(ang), np.zeros(6)]
    p0 = np.vstack([ring, [[0.0, 0.0, 0.03], [0.0, 0.0, -0.03]]])
    p = np.stack([p0, p0 * [1.0, 1.0, 0.5]])  # the hand flattens along z
    cs = ellipsoid_closure_signature(p)
    np.testing.assert_allclose(cs.axis, [0.0, 0.0, 1.0], atol=1e-6)
    assert cs.extras["ill_defined_axes"] == [[1, 2]]  # the two round axes, after the elected z
    assert any("ill-defined" in w for w in cs.extras["warnings"])
    squeezed = ellipsoid_closure_signature(np.stack([p0 * [1.0, 0.7, 1.0], p0 * [1.0, 0.7, 0.5]]))
    assert "ill_defined_axes" not in squeezed.extras and "warnings" not in squeezed.extras


# ----------------------------------------------------------------------------------------------------- errors


def test_unknown_method() -> None:
    p = close(open_hand(np.eye(3)), np.eye(3), np.array([0.6, 1.0, 1.0]), 3)
    with pytest.raises(InvalidInput) as info:
        compute_closure_signature(trajectory(p), "voronoi")  # type: ignore[arg-type]
    assert info.value.field == "method"
    assert info.value.choices == ["ellipsoid", "mesh", "pca"]


@pytest.mark.parametrize("method", METHODS)
def test_unknown_criterion(method: str) -> None:
    p = close(open_hand(np.eye(3)), np.eye(3), np.array([0.6, 1.0, 1.0]), 3)
    with pytest.raises(InvalidInput) as info:
        compute_closure_signature(trajectory(p), method, criterion="percent")  # type: ignore[arg-type]
    assert info.value.field == "criterion"
    assert info.value.value == "percent"
    assert info.value.choices == ["absolute", "relative"]
    with pytest.raises(InvalidInput, match="criterion"):
        ellipsoid_closure_signature(p, criterion="Absolute")  # type: ignore[arg-type]


@pytest.mark.parametrize("method", ["pca", "mesh"])
def test_pca_and_mesh_ignore_the_criterion(method: str) -> None:
    frame = rotation((0.4, 0.3, 0.2, 0.1))
    traj = trajectory(close(open_hand(frame), frame, np.array([0.6, 0.9, 1.0]), 6, noise=1e-4))
    results = [compute_closure_signature(traj, method, criterion=c) for c in CRITERIA]  # type: ignore[arg-type]
    for cs in results:
        assert "criterion" not in cs.params
    assert results[0].to_json_dict() == results[1].to_json_dict()


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


@given(
    quaternions,
    st.tuples(*[st.floats(0.5, 1.5)] * 3),
    st.integers(0, 2),
)
@settings(max_examples=40, deadline=None)
def test_mesh_refuses_a_mirrored_closure_and_keeps_a_proper_one(
    q: tuple[float, float, float, float], scales: tuple[float, float, float], mirrored_axis: int
) -> None:
    """x_T = x_0 R diag(s) (det > 0) is a deformation; the same with one axis flipped (det < 0) mirrors the points:
    flagged with a warning and a negative signed stretch, never reported as plain deformations with no word."""
    frame = rotation(q)
    x0 = open_hand(np.eye(3))
    stretch = np.diag(scales) @ frame
    proper = np.stack([x0, x0 @ stretch.T])
    cs = mesh_closure_signature(proper, source="reference_points")
    assert cs.extras["det_F"] > 0 and "warnings" not in cs.extras
    assert cs.extras["signed_stretches"] == cs.extras["stretches"]
    flip = np.eye(3)
    flip[mirrored_axis, mirrored_axis] = -1.0
    mirror = np.stack([x0, x0 @ (flip @ stretch).T])
    flagged = mesh_closure_signature(mirror, source="reference_points")
    assert flagged.extras["det_F"] < 0 and any("mirrors" in w for w in flagged.extras["warnings"])
    signed = flagged.extras["signed_stretches"]
    assert sum(v < 0 for v in signed) == 1
    assert np.allclose(np.abs(signed), flagged.extras["stretches"])
    assert abs(flagged.extras["rotation_angle"]) <= math.pi


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


def test_plot_magnitude_label_names_the_unit_and_the_criterion() -> None:
    frame = rotation((0.9, 0.2, 0.1, 0.3))
    traj = trajectory(close(open_hand(frame), frame, np.array([0.6, 0.9, 1.0]), 4))
    # 60 -> 36 mm along the first axis
    assert (
        magnitude_label(compute_closure_signature(traj, "ellipsoid")) == "-0.024 m (absolute change of the half-width)"
    )
    relative = compute_closure_signature(traj, "ellipsoid", criterion="relative")
    assert magnitude_label(relative) == "-0.4 (relative change of the half-width)"
    assert magnitude_label(compute_closure_signature(traj, "pca")).endswith(" m")
    assert "change" not in magnitude_label(compute_closure_signature(traj, "mesh"))
