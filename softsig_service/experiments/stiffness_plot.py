"""A picture of a stiffness signature: break force per pull direction beside the translational stiffness ellipsoid.

Uses matplotlib's object API with the Agg canvas (no pyplot, no global backend switch), so it is safe in worker
processes and servers without a display. Everything is drawn in the hand frame.

* Left: one arrow per pull direction from the origin, of length = break force [N] along the direction, coloured
  by the force; a capped direction (the object held at the cap) is drawn dashed with an open marker at its tip;
  a grasp the hand does not hold alone (every force 0) is stated in the title. The scale is robust
  (:func:`robust_limit`): a force far above the others (beyond the upper quartile plus 3 interquartile ranges) is
  drawn at that limit with a red cross and its value written, so one outlier does not squash the rest.
* Right: the translational stiffness ellipsoid ``{x : x = sum_k k_k a_k r_k, |a| = 1}`` — semi-axes equal to the
  principal translational stiffnesses ``k_k`` [N/m] along their directions ``r_k`` (eigen-decomposition of
  ``K[:3, :3]``), with the three principal axes drawn and labelled.
"""

from __future__ import annotations

from pathlib import Path
from typing import cast

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.axes3d import Axes3D
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput
from softsig_service.signatures.stiffness_types import StiffnessSignature

PLOT_SUFFIXES: tuple[str, ...] = (".png", ".pdf", ".svg")


def plot_stiffness_signature(ss: StiffnessSignature, path: Path | str) -> Path:
    """Draw ``ss`` and save it to ``path`` (.png, .pdf or .svg); return the path."""
    out = Path(path)
    if out.suffix.lower() not in PLOT_SUFFIXES:
        raise InvalidInput("unsupported plot file type", field="path", value=out.suffix, choices=PLOT_SUFFIXES)
    fig = Figure(figsize=(12.0, 5.6), layout="tight")
    FigureCanvasAgg(fig)
    ax_f = cast(Axes3D, fig.add_subplot(1, 2, 1, projection="3d"))
    ax_k = cast(Axes3D, fig.add_subplot(1, 2, 2, projection="3d"))
    _draw_break_forces(fig, ax_f, ss)
    _draw_ellipsoid(ax_k, ss)
    obj = ss.object.get("name") or ss.object.get("kind", "object")
    fig.suptitle(f"Stiffness signature: {ss.hand or 'hand'} holding {obj} (frame: {ss.frame_id})")
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    return out


OUTLIER_IQR = 3.0
"""A break force beyond the upper quartile plus this many interquartile ranges is an outlier of the plot's scale."""


def robust_limit(forces: NDArray[np.float64]) -> float:
    """The plot's force scale [N]: the largest force, or, when some lie beyond ``Q3 + OUTLIER_IQR * IQR`` (and
    at least four forces are given), the largest force within that fence."""
    f = np.asarray(forces, dtype=np.float64)
    if len(f) < 4:
        return float(f.max())
    q1, q3 = np.percentile(f, [25.0, 75.0])
    fence = q3 + OUTLIER_IQR * (q3 - q1)
    inside = f[f <= fence]
    return float(inside.max()) if len(inside) and inside.max() > 0.0 else float(f.max())


def _draw_break_forces(fig: Figure, ax: Axes3D, ss: StiffnessSignature) -> None:
    ax.set_xlabel("x [N]")
    ax.set_ylabel("y [N]")
    ax.set_zlabel("z [N]")
    bf = ss.break_forces
    if not bf:
        ax.set_title("break forces: no pull test")
        return
    forces = np.array([b.force for b in bf])
    fmax = float(forces.max())
    if fmax <= 0.0:
        ax.set_title("break forces: the hand does not hold the object alone (all 0 N)")
        _equal_axes(ax, np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]))
        return
    limit = robust_limit(forces)
    norm = Normalize(vmin=0.0, vmax=limit)
    cmap = colormaps["viridis"]
    tips = []
    outliers = 0
    for b in bf:
        tip = min(b.force, limit) * np.asarray(b.direction)
        tips.append(tip)
        color = cmap(norm(min(b.force, limit)))
        if b.force > limit:
            outliers += 1
            ax.scatter([tip[0]], [tip[1]], [tip[2]], color="red", s=60, marker="x")
            ax.text(tip[0], tip[1], tip[2], f" {b.force:.0f} N", color="red", fontsize=8)
        ax.plot([0, tip[0]], [0, tip[1]], [0, tip[2]], color=color, linestyle="--" if b.capped else "-", linewidth=1.4)
        ax.scatter(
            [tip[0]],
            [tip[1]],
            [tip[2]],
            color=color,
            s=22,
            marker="o" if not b.capped else "^",
            facecolors="none" if b.capped else color,
        )
    pts = np.array(tips)
    _equal_axes(ax, np.vstack([pts, np.zeros((1, 3))]))  # the origin (the grasped centre) in view
    mappable = ScalarMappable(norm=norm, cmap=cmap)
    mappable.set_array([])
    fig.colorbar(mappable, ax=ax, shrink=0.6, label="break force [N]")
    capped = sum(1 for b in bf if b.capped)
    title = f"break forces ({len(bf)} directions"
    title += f", {capped} held at the cap" if capped else ""
    title += f", {outliers} beyond the scale drawn at {limit:.1f} N (x)" if outliers else ""
    ax.set_title(title + ")", fontsize=9)


def _draw_ellipsoid(ax: Axes3D, ss: StiffnessSignature) -> None:
    vals = np.maximum(np.asarray(ss.principal_translational.values, dtype=np.float64), 0.0)
    dirs = np.asarray(ss.principal_translational.directions, dtype=np.float64)
    u, v = np.meshgrid(np.linspace(0.0, 2.0 * np.pi, 36), np.linspace(0.0, np.pi, 18))
    sphere = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], axis=-1)
    pts = sphere @ (dirs.T * vals).T  # x = sum_k vals_k s_k r_k
    ax.plot_wireframe(pts[..., 0], pts[..., 1], pts[..., 2], color="tab:blue", linewidth=0.4, alpha=0.6)
    colors = ("tab:red", "tab:green", "tab:purple")
    for k in range(3):
        a = vals[k] * dirs[k]
        ax.plot(
            [-a[0], a[0]],
            [-a[1], a[1]],
            [-a[2], a[2]],
            color=colors[k],
            linewidth=2.0,
            label=f"k{k + 1} = {vals[k]:.4g} N/m",
        )
    _equal_axes(ax, pts.reshape(-1, 3))
    ax.set_xlabel("x [N/m]")
    ax.set_ylabel("y [N/m]")
    ax.set_zlabel("z [N/m]")
    ax.set_title("translational stiffness ellipsoid (K[:3, :3])")
    ax.legend(loc="upper left", fontsize=8)


def _equal_axes(ax: Axes3D, pts: NDArray[np.float64]) -> None:
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = max(float((hi - lo).max()) / 2.0, 1e-9) * 1.1
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
