"""A picture of a closure signature: a 3-D view and the three projections of the frame the points are in.

The 3-D view (orthographic) sits beside the top (x-y, seen from +z), front (x-z, seen from -y) and side (y-z, seen
from +x) projections of the frame of the trajectory (the hand frame, or the grasp frame when the hand declares
one). Every panel shows the reference points open (circles) and closed (triangles) joined by their tracks, E_0 and
E_T (ellipsoid method: wireframes in 3-D, their outlines in the projections) and the CS axis through its anchor
(the CS is an axis: both senses are valid). All panels share one scale, equal along x, y and z, so a horizontal
CS looks horizontal. Point names are written in the projections only, each at the first of 16 places around its
point that overlaps no other name, no point and no panel title (a name with no free place is left out of that
panel). The CS's angle to each axis of the frame [deg] and its numbers are in a fifth panel with no axes; the legend is
under the 3-D view.

Uses matplotlib's object API with the Agg canvas (no pyplot, no global backend switch), so it is safe in
worker processes and servers without a display.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal, cast

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.transforms import Bbox
from mpl_toolkits.mplot3d.axes3d import Axes3D
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput
from softsig_service.geometry.ellipsoid import Ellipsoid
from softsig_service.hands.trajectory import ClosureTrajectory
from softsig_service.signatures.closure_types import ClosureSignature

PLOT_SUFFIXES: tuple[str, ...] = (".png", ".pdf", ".svg")
PROJECTIONS: tuple[tuple[str, int, int], ...] = (
    ("top (x-y), seen from +z", 0, 1),
    ("front (x-z), seen from -y", 0, 2),
    ("side (y-z), seen from +x", 1, 2),
)
"""The 2-D panels: title and the two coordinates (0 = x, 1 = y, 2 = z) drawn horizontally and vertically."""
_OPEN, _CLOSED, _CS = "tab:blue", "tab:red", "k"
_Drawn = tuple[Ellipsoid, str, str, Literal["-", "--"]]  # an ellipsoid, its colour, legend label and line style


def plot_closure_signature(traj: ClosureTrajectory, cs: ClosureSignature, path: Path | str) -> Path:
    """Draw ``cs`` over ``traj`` (:func:`closure_signature_figure`) and save it to ``path`` (.png, .pdf or .svg);
    return the path."""
    out = Path(path)
    if out.suffix.lower() not in PLOT_SUFFIXES:
        raise InvalidInput("unsupported plot file type", field="path", value=out.suffix, choices=PLOT_SUFFIXES)
    fig = closure_signature_figure(traj, cs)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    return out


def axis_angles(axis: NDArray[np.float64]) -> tuple[float, float, float]:
    """The angles [deg, 0 to 90] between the line along ``axis`` (3-vector, any length and sense) and the x, y and
    z axes of its frame."""
    v = np.asarray(axis, dtype=np.float64)
    v = v / np.linalg.norm(v)
    x, y, z = (math.degrees(math.acos(min(1.0, abs(float(c))))) for c in v)
    return x, y, z


def closure_signature_figure(traj: ClosureTrajectory, cs: ClosureSignature) -> Figure:
    """The figure of :func:`plot_closure_signature` (module docstring): five axes, the 3-D view, the top, front and
    side projections, then the numbers panel (its axis off); the legend is under the 3-D view. Lengths [m] in the
    trajectory's frame."""
    fig = Figure(figsize=(14.0, 8.0))
    FigureCanvasAgg(fig)
    left = fig.add_gridspec(1, 1, left=0.0, right=0.44, bottom=0.13, top=0.9)
    right = fig.add_gridspec(2, 2, left=0.48, right=0.985, bottom=0.07, top=0.88, wspace=0.3, hspace=0.3)
    ax3 = cast(Axes3D, fig.add_subplot(left[0, 0], projection="3d"))
    flat = [fig.add_subplot(right[0, 0]), fig.add_subplot(right[0, 1]), fig.add_subplot(right[1, 0])]
    info = fig.add_subplot(right[1, 1])

    p = traj.positions
    ellipsoids: list[_Drawn] = []
    if cs.initial_ellipsoid is not None:
        ellipsoids.append((cs.initial_ellipsoid, _OPEN, "E_0 (open)", "-"))
    if cs.final_ellipsoid is not None:
        ellipsoids.append((cs.final_ellipsoid, _CLOSED, "E_T (closed)", "--"))
    extent: list[NDArray[np.float64]] = [p[0], p[-1]]
    for e, *_ in ellipsoids:
        extent.append(np.stack([c.ravel() for c in _ellipsoid_mesh(e)], axis=1))
    cloud = np.concatenate(extent)
    size = float(np.max(np.ptp(cloud, axis=0)))
    length = 0.6 * size if size > 0 else 1.0
    a, v = np.asarray(cs.anchor, dtype=np.float64), np.asarray(cs.axis, dtype=np.float64)
    line = np.stack([a - length * v, a + length * v])
    lo, hi = np.concatenate([cloud, line]).min(axis=0), np.concatenate([cloud, line]).max(axis=0)
    mid, half = 0.5 * (lo + hi), 0.5 * float(np.max(hi - lo)) * 1.08 or 1e-3

    _draw_3d(ax3, traj, cs, ellipsoids, line, length)
    _equal_aspect(ax3, mid, half)
    frame = f"{traj.frame_id} frame"
    for ax, (title, i, j) in zip(flat, PROJECTIONS, strict=True):
        _draw_projection(ax, traj, ellipsoids, line, i, j)
        ax.set_xlim(mid[i] - half, mid[i] + half)
        ax.set_ylim(mid[j] - half, mid[j] + half)
        ax.set_aspect("equal", adjustable="box")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(f"{'xyz'[i]} [m]")
        ax.set_ylabel(f"{'xyz'[j]} [m]")
        ax.grid(True, color="0.9", linewidth=0.6)
        ax.tick_params(labelsize=8)

    info.set_axis_off()
    info.text(0.0, 0.95, _numbers(cs, frame), transform=info.transAxes, fontsize=10, va="top", ha="left",
              family="monospace", linespacing=1.4)  # fmt: skip
    fig.legend(handles=_legend_handles(ellipsoids), loc="lower left", bbox_to_anchor=(0.03, 0.01), ncol=2,
               fontsize=9, frameon=False)  # fmt: skip
    flag = " (ambiguous)" if cs.ambiguous else ""
    fig.suptitle(
        f"{traj.hand}: {cs.method} closure signature in the {frame}\n"
        f"magnitude {magnitude_label(cs)}, distinctness {cs.distinctness:.3g}{flag}",
        fontsize=12,
    )
    fig.canvas.draw()  # lays the panels out: the names are placed in the final display coordinates
    for ax, (_, i, j) in zip(flat, PROJECTIONS, strict=True):
        _place_names(ax, traj, i, j)
    return fig


def _legend_handles(ellipsoids: list[_Drawn]) -> list[Line2D]:
    """The legend's entries: points, tracks, the ellipsoids drawn and the CS."""
    handles = [
        Line2D([], [], color=_OPEN, marker="o", linestyle="none", label="open reference points (t = 0)"),
        Line2D([], [], color=_CLOSED, marker="^", linestyle="none", label="closed reference points (t = T)"),
        Line2D([], [], color="0.6", linewidth=0.8, label="tracks"),
    ]
    handles += [Line2D([], [], color=c, linestyle=style, label=label) for _, c, label, style in ellipsoids]
    handles.append(
        Line2D([], [], color=_CS, linestyle="--", marker=">", label="CS axis through its anchor (both senses)")
    )
    return handles


def _numbers(cs: ClosureSignature, frame: str) -> str:
    """The numbers panel's text: the CS axis and anchor, its angle to each axis of ``frame`` [deg], and the angle
    of its x-y part from +y and of the axis from the x-y plane [deg]."""
    v = np.asarray(cs.axis, dtype=np.float64)
    ax_x, ax_y, ax_z = axis_angles(v)
    horizontal = math.degrees(math.atan2(abs(float(v[0])), abs(float(v[1]))))
    return "\n".join(
        [
            f"CS axis, {frame}:",
            f"  ({v[0]:+.3f}, {v[1]:+.3f}, {v[2]:+.3f})",
            "anchor [m]:",
            "  (" + ", ".join(f"{c:+.4f}" for c in cs.anchor) + ")",
            "angle of the CS to",
            f"  x: {ax_x:5.1f} deg",
            f"  y: {ax_y:5.1f} deg",
            f"  z: {ax_z:5.1f} deg",
            f"x-y part from y: {horizontal:5.1f} deg",
            f"out of the x-y plane: {90.0 - ax_z:5.1f} deg",
        ]
    )


def _draw_3d(
    ax: Axes3D,
    traj: ClosureTrajectory,
    cs: ClosureSignature,
    ellipsoids: list[_Drawn],
    line: NDArray[np.float64],
    length: float,
) -> None:
    """The 3-D panel: tracks, points, ellipsoid wireframes and the CS arrow with its dashed line."""
    p = traj.positions
    for i in range(traj.n_points):
        ax.plot(p[:, i, 0], p[:, i, 1], p[:, i, 2], color="0.6", linewidth=0.8)
    ax.scatter(p[0, :, 0], p[0, :, 1], p[0, :, 2], color=_OPEN, marker="o")
    ax.scatter(p[-1, :, 0], p[-1, :, 1], p[-1, :, 2], color=_CLOSED, marker="^")
    for e, color, _, style in ellipsoids:
        xs, ys, zs = _ellipsoid_mesh(e)
        ax.plot_wireframe(xs, ys, zs, color=color, linewidth=0.4, alpha=0.5, linestyle=style)
    a, v = cs.anchor, cs.axis
    ax.quiver(a[0], a[1], a[2], v[0], v[1], v[2], length=length, arrow_length_ratio=0.15, color=_CS, linewidth=2.0)
    ax.plot(line[:, 0], line[:, 1], line[:, 2], color=_CS, linestyle="--", linewidth=0.8)
    ax.set_proj_type("ortho")
    ax.view_init(elev=20.0, azim=_broadside_azimuth(np.asarray(v, dtype=np.float64)))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.tick_params(labelsize=7)
    ax.set_title("3-D view", fontsize=10)


def _broadside_azimuth(axis: NDArray[np.float64]) -> float:
    """The 3-D view's azimuth [deg]: the eye in the direction, perpendicular to the x-y part of ``axis``, nearer
    matplotlib's default -60 deg, so that the axis is seen broadside and its tilt from the x-y plane shows as it is
    (an axis in the x-y plane is drawn level). -60 deg for an axis along z."""
    if math.hypot(float(axis[0]), float(axis[1])) < 1e-9:
        return -60.0
    heading = math.degrees(math.atan2(float(axis[1]), float(axis[0])))
    eyes = [heading + 90.0, heading - 90.0]
    return min(eyes, key=lambda e: abs((e + 60.0 + 180.0) % 360.0 - 180.0))


def _draw_projection(
    ax: Axes,
    traj: ClosureTrajectory,
    ellipsoids: list[_Drawn],
    line: NDArray[np.float64],
    i: int,
    j: int,
) -> None:
    """One projection on coordinates ``i`` (across) and ``j`` (up): tracks, points, ellipse outlines, CS."""
    p = traj.positions
    for k in range(traj.n_points):
        ax.plot(p[:, k, i], p[:, k, j], color="0.6", linewidth=0.8, zorder=1)
    ax.scatter(p[0, :, i], p[0, :, j], color=_OPEN, marker="o", s=22, zorder=3)
    ax.scatter(p[-1, :, i], p[-1, :, j], color=_CLOSED, marker="^", s=26, zorder=3)
    for e, color, _, style in ellipsoids:
        outline = _outline(e, i, j)
        ax.plot(outline[:, 0], outline[:, 1], color=color, linestyle=style, linewidth=0.9, alpha=0.8, zorder=2)
    ax.plot(line[:, i], line[:, j], color=_CS, linestyle="--", linewidth=0.9, zorder=2)
    centre = line.mean(axis=0)
    ax.annotate("", xy=(line[1, i], line[1, j]), xytext=(centre[i], centre[j]),
                arrowprops={"arrowstyle": "-|>", "color": _CS, "linewidth": 1.8, "shrinkA": 0, "shrinkB": 0},
                zorder=4)  # fmt: skip


_OFFSETS = tuple(
    (r * math.cos(t), r * math.sin(t)) for r in (7.0, 16.0) for t in np.deg2rad([45, 135, -45, -135, 0, 180, 90, -90])
)
"""Where a name may go, relative to its point [pt]."""


def _place_names(ax: Axes, traj: ClosureTrajectory, i: int, j: int) -> None:
    """Write each open point's name at the first place of :data:`_OFFSETS` where it overlaps no name already
    written, no point of the panel and no title, inside the panel; leave it out where there is none."""
    renderer = cast(FigureCanvasAgg, ax.figure.canvas).get_renderer()
    p = traj.positions
    to_px = ax.transData.transform
    dots = np.concatenate([to_px(p[0][:, [i, j]]), to_px(p[-1][:, [i, j]])])
    r = 4.0 * renderer.points_to_pixels(1.0)
    taken: list[Bbox] = [Bbox.from_extents(x - r, y - r, x + r, y + r) for x, y in dots]
    taken.append(ax.title.get_window_extent(renderer))
    inside = ax.get_window_extent(renderer)
    for name, xyz in zip(traj.point_names, p[0], strict=True):
        for dx, dy in _OFFSETS:
            text = ax.annotate(name, (xyz[i], xyz[j]), xytext=(dx, dy), textcoords="offset points", fontsize=7.5,
                               color=_OPEN, ha="left" if dx > 0.5 else "right" if dx < -0.5 else "center",
                               va="bottom" if dy > 0.5 else "top" if dy < -0.5 else "center")  # fmt: skip
            box = text.get_window_extent(renderer)
            fits = inside.containsx(box.x0) and inside.containsx(box.x1)
            fits = fits and inside.containsy(box.y0) and inside.containsy(box.y1)
            if fits and not any(box.overlaps(t) for t in taken):
                taken.append(box)
                break
            text.remove()


def _outline(e: Ellipsoid, i: int, j: int, n: int = 120) -> NDArray[np.float64]:
    """The outline (n, 2) [m] of the shadow of ``e`` on coordinates ``i`` and ``j``: the ellipse of the 2x2 block
    of ``e``'s inverse shape matrix (axes diag(semi_axes^2) axes^T)."""
    cov = (e.axes * e.semi_axes**2) @ e.axes.T
    block = cov[np.ix_([i, j], [i, j])]
    root = np.linalg.cholesky(block + 1e-18 * np.eye(2))
    t = np.linspace(0.0, 2.0 * np.pi, n)
    return e.center[[i, j]] + np.stack([np.cos(t), np.sin(t)], axis=1) @ root.T


def magnitude_label(cs: ClosureSignature) -> str:
    """The CS magnitude with its unit and, for the ellipsoid method, what it measures, e.g.
    "+0.0123 m (absolute change of the half-width)" or "+1.4 (relative change of the half-width)"."""
    unit = cs.extras.get("magnitude_unit", "")
    text = f"{cs.magnitude:+.3g}" + (f" {unit}" if unit and unit != "1" else "")
    criterion = cs.params.get("criterion") if cs.method == "ellipsoid" else None
    if criterion is not None:
        text += f" ({criterion} change of the half-width)"
    return text


def _ellipsoid_mesh(
    e: Ellipsoid, n_u: int = 24, n_v: int = 12
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Grid points of the surface of ``e`` [m]: three (n_v, n_u) arrays for ``plot_wireframe``."""
    u = np.linspace(0.0, 2.0 * np.pi, n_u)
    v = np.linspace(0.0, np.pi, n_v)
    unit = np.stack(
        [
            np.outer(np.sin(v), np.cos(u)),
            np.outer(np.sin(v), np.sin(u)),
            np.outer(np.cos(v), np.ones_like(u)),
        ],
        axis=-1,
    )
    pts = e.center + (unit * e.semi_axes) @ e.axes.T
    return pts[..., 0], pts[..., 1], pts[..., 2]


def _equal_aspect(ax: Axes3D, mid: NDArray[np.float64], half: float) -> None:
    """Cube limits ``mid`` +- ``half`` [m] and a 1:1:1 box, so lengths read the same along x, y and z."""
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
