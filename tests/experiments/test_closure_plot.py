"""The closure-signature picture: a 3-D view beside the top, front and side projections, one equal scale, names
that do not overlap, and the CS's angles to the frame's axes written as the CS vector gives them."""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.text import Annotation, Text
from mpl_toolkits.mplot3d import proj3d
from mpl_toolkits.mplot3d.axes3d import Axes3D
from numpy.typing import NDArray

from softsig_service.experiments.closure_plot import closure_signature_figure, plot_closure_signature
from softsig_service.hands.trajectory import ClosureTrajectory
from softsig_service.signatures.closure import compute_closure_signature


def frame_with(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """An orthonormal right-handed frame (columns) whose second column is ``u``."""
    u = u / np.linalg.norm(u)
    a = np.cross(u, [0.0, 0.0, 1.0]) if abs(u[2]) < 0.9 else np.cross(u, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    return np.stack([a, u, np.cross(a, u)], axis=1)


def shrinking_along(u: NDArray[np.float64], frames: int = 8) -> ClosureTrajectory:
    """Six points at +-(40, 80, 20) mm along the columns of :func:`frame_with` (``u`` carries the 80 mm, so the
    MVEE's axes are the frame's columns) whose extent along ``u`` shrinks to 40 % while the others stay: the
    ellipsoid CS is the line along ``u``."""
    R = frame_with(u)
    local = np.concatenate([np.diag([0.04, 0.08, 0.02]), -np.diag([0.04, 0.08, 0.02])])
    centre = np.array([0.01, -0.02, 0.08])
    positions = []
    for s in np.linspace(0.0, 1.0, frames):
        squeeze = np.diag([1.0, 1.0 - 0.6 * s, 1.0])
        positions.append(centre + local @ squeeze @ R.T)
    names = ("a_plus", "b_plus", "c_plus", "a_minus", "b_minus", "c_minus")
    return ClosureTrajectory(
        hand="synthetic", times=np.linspace(0.0, 1.0, frames), point_names=names, positions=np.array(positions)
    )


def written_angles(fig_texts: list[str]) -> dict[str, float]:
    """The angles [deg] the numbers panel gives, keyed x, y, z, 'xy' (x-y part from y) and 'plane'."""
    (text,) = [t for t in fig_texts if "angle of the CS to" in t]
    out = {k: float(v) for k, v in re.findall(r"^\s+([xyz]):\s+([-\d.]+) deg$", text, flags=re.M)}
    out["xy"] = float(re.search(r"x-y part from y:\s+([-\d.]+) deg", text).group(1))  # type: ignore[union-attr]
    out["plane"] = float(re.search(r"out of the x-y plane:\s+([-\d.]+) deg", text).group(1))  # type: ignore[union-attr]
    return out


@pytest.mark.parametrize(
    "u",
    [np.array([-0.31, 0.95, 0.04]), np.array([0.5, 0.3, 0.81]), np.array([0.0, 1.0, 0.0])],
    ids=["softhand_like", "tilted", "along_y"],
)
def test_the_written_angles_are_those_of_the_cs_vector(u: NDArray[np.float64]) -> None:
    traj = shrinking_along(u)
    cs = compute_closure_signature(traj, "ellipsoid")
    unit = u / np.linalg.norm(u)
    assert abs(float(np.dot(cs.axis, unit))) > 1 - 1e-6  # the construction's CS is the line along u
    fig = closure_signature_figure(traj, cs)
    angles = written_angles([t.get_text() for ax in fig.axes for t in ax.texts])
    for k, name in enumerate("xyz"):
        expected = math.degrees(math.acos(abs(unit[k])))
        assert angles[name] == pytest.approx(expected, abs=0.051), name
    assert angles["xy"] == pytest.approx(math.degrees(math.atan2(abs(unit[0]), abs(unit[1]))), abs=0.051)
    assert angles["plane"] == pytest.approx(math.degrees(math.asin(abs(unit[2]))), abs=0.051)


def test_four_panels_one_equal_scale_and_names_that_do_not_overlap() -> None:
    traj = shrinking_along(np.array([-0.31, 0.95, 0.04]))
    cs = compute_closure_signature(traj, "ellipsoid")
    fig = closure_signature_figure(traj, cs)
    assert len(fig.axes) == 5
    assert sum(isinstance(ax, Axes3D) for ax in fig.axes) == 1
    flat = [ax for ax in fig.axes if not isinstance(ax, Axes3D) and ax.axison]
    assert len(flat) == 3  # and the numbers panel, its axis off
    assert [ax.get_xlabel()[0] + ax.get_ylabel()[0] for ax in flat] == ["xy", "xz", "yz"]
    spans = {round(float(np.ptp(lim)), 9) for ax in flat for lim in (ax.get_xlim(), ax.get_ylim())}
    assert len(spans) == 1  # every 2-D axis covers the same length
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    for ax in flat:
        assert ax.get_aspect() == 1.0
        box = ax.get_window_extent(renderer)
        assert box.width == pytest.approx(box.height, rel=0.01)  # equal limits and aspect: a square panel
        names = [t for t in ax.texts if isinstance(t, Annotation) and t.get_text() in traj.point_names]
        assert len(names) >= 4, [t.get_text() for t in names]
        extents = [t.get_window_extent(renderer) for t in names] + [ax.title.get_window_extent(renderer)]
        for a, b in itertools.combinations(extents, 2):
            assert not a.overlaps(b)
    top = flat[0]
    assert len([t for t in top.texts if isinstance(t, Annotation) and t.get_text()]) == 6  # every name, top view


def test_a_cs_in_the_x_y_plane_is_drawn_level_in_the_3d_view() -> None:
    traj = shrinking_along(np.array([-0.31, 0.95, 0.0]))
    cs = compute_closure_signature(traj, "ellipsoid")
    fig = closure_signature_figure(traj, cs)
    (ax3,) = [ax for ax in fig.axes if isinstance(ax, Axes3D)]
    ends = np.stack([cs.anchor - 0.05 * cs.axis, cs.anchor + 0.05 * cs.axis])
    x, y, _ = proj3d.proj_transform(ends[:, 0], ends[:, 1], ends[:, 2], ax3.get_proj())
    px = ax3.transData.transform(np.stack([x, y], axis=1))
    dx, dy = px[1] - px[0]
    assert abs(dy) < 0.02 * abs(dx)  # level on the screen
    assert math.hypot(dx, dy) > 0.1 * ax3.get_window_extent().width  # seen broadside, not end on


def test_the_png_is_a_light_non_trivial_picture(tmp_path: Path) -> None:
    traj = shrinking_along(np.array([0.5, 0.3, 0.81]))
    cs = compute_closure_signature(traj, "ellipsoid")
    out = plot_closure_signature(traj, cs, tmp_path / "cs.png")
    rgb = matplotlib.image.imread(out)[..., :3]
    assert rgb.shape == (800, 1400, 3)
    grey = rgb.mean(axis=2)
    assert np.median(grey) > 0.95 and grey[:5, :5].min() > 0.95  # light background
    assert grey.std() > 0.05 and (grey < 0.3).mean() > 0.003  # ink: lines, points and text
    assert len(np.unique((rgb * 255).astype(np.uint8).reshape(-1, 3), axis=0)) > 50


def test_the_frame_is_named_and_unknown_file_types_are_refused(tmp_path: Path) -> None:
    traj = shrinking_along(np.array([0.0, 1.0, 0.0]))
    cs = compute_closure_signature(traj, "pca")
    fig = closure_signature_figure(traj, cs)
    title = fig.get_suptitle()
    assert "hand frame" in title and "pca" in title
    texts: list[Text] = [t for ax in fig.axes for t in ax.texts]
    assert any("CS axis, hand frame" in t.get_text() for t in texts)
    assert isinstance(fig.axes[1], Axes)
    from softsig_service.errors import InvalidInput

    with pytest.raises(InvalidInput):
        plot_closure_signature(traj, cs, tmp_path / "cs.bmp")
