"""A 3-D picture of a closure signature: the reference points open and closed, E_0 and E_T, the CS axis.

Uses matplotlib's object API with the Agg canvas (no pyplot, no global backend switch), so it is safe in
worker processes and servers without a display. Everything is drawn in the hand frame [m] with equal axis
scales.
"""

from __future__ import annotations

from pathlib import Path
from typing import cast

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.axes3d import Axes3D
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput
from softsig_service.geometry.ellipsoid import Ellipsoid
from softsig_service.hands.trajectory import ClosureTrajectory
from softsig_service.signatures.closure_types import ClosureSignature

PLOT_SUFFIXES: tuple[str, ...] = (".png", ".pdf", ".svg")


def plot_closure_signature(traj: ClosureTrajectory, cs: ClosureSignature, path: Path | str) -> Path:
    """Draw ``cs`` over ``traj`` and save it to ``path`` (.png, .pdf or .svg); return the path.

    Shows every reference point at t = 0 (open, circles) and t = T-1 (closed, triangles) joined by its track,
    the initial and final ellipsoids as wireframes (ellipsoid method), and the CS axis as an arrow from the
    anchor with a dashed line through it (the CS is an axis: both senses are valid).
    """
    out = Path(path)
    if out.suffix.lower() not in PLOT_SUFFIXES:
        raise InvalidInput("unsupported plot file type", field="path", value=out.suffix, choices=PLOT_SUFFIXES)

    fig = Figure(figsize=(7.0, 6.0), layout="tight")
    FigureCanvasAgg(fig)
    ax = cast(Axes3D, fig.add_subplot(projection="3d"))
    p = traj.positions
    extent: list[NDArray[np.float64]] = [p[0], p[-1]]

    for i in range(traj.n_points):
        ax.plot(p[:, i, 0], p[:, i, 1], p[:, i, 2], color="0.6", linewidth=0.8)
    ax.scatter(p[0, :, 0], p[0, :, 1], p[0, :, 2], color="tab:blue", marker="o", label="open (t = 0)")
    ax.scatter(p[-1, :, 0], p[-1, :, 1], p[-1, :, 2], color="tab:red", marker="^", label="closed (t = T)")
    for name, xyz in zip(traj.point_names, p[0], strict=True):
        ax.text(xyz[0], xyz[1], xyz[2], f" {name}", fontsize=7, color="tab:blue")

    for ellipsoid, color, label in (
        (cs.initial_ellipsoid, "tab:blue", "E_0"),
        (cs.final_ellipsoid, "tab:red", "E_T"),
    ):
        if ellipsoid is None:
            continue
        xs, ys, zs = _ellipsoid_mesh(ellipsoid)
        ax.plot_wireframe(xs, ys, zs, color=color, linewidth=0.4, alpha=0.5, label=label)
        extent.append(np.stack([xs.ravel(), ys.ravel(), zs.ravel()], axis=1))

    cloud = np.concatenate(extent)
    size = float(np.max(np.ptp(cloud, axis=0)))
    length = 0.6 * size if size > 0 else 1.0
    a, v = cs.anchor, cs.axis
    ax.quiver(
        a[0],
        a[1],
        a[2],
        v[0],
        v[1],
        v[2],
        length=length,
        arrow_length_ratio=0.15,
        color="k",
        linewidth=2.0,
        label="CS axis",
    )
    line = np.stack([a - length * v, a + length * v])
    ax.plot(line[:, 0], line[:, 1], line[:, 2], color="k", linestyle="--", linewidth=0.8)
    extent.append(line)

    _equal_aspect(ax, np.concatenate(extent))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    flag = " (ambiguous)" if cs.ambiguous else ""
    ax.set_title(
        f"{traj.hand}: {cs.method} closure signature, hand frame\n"
        f"magnitude {magnitude_label(cs)}, distinctness {cs.distinctness:.3g}{flag}",
        fontsize=10,
    )
    ax.legend(loc="upper left", fontsize=8)
    fig.savefig(out)
    return out


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


def _equal_aspect(ax: Axes3D, points: NDArray[np.float64]) -> None:
    """Cube limits around ``points`` and a 1:1:1 box, so lengths read the same along x, y and z."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    mid = 0.5 * (lo + hi)
    half = 0.5 * float(np.max(hi - lo)) or 1e-3
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
