"""A plan's image: the object, the hand's footprint and the grasp seen from above (matplotlib, Agg), as PNG bytes."""

from __future__ import annotations

import io
import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from softsig_service.config import Settings
    from softsig_service.signatures.closure_types import Criterion


def render_plan_png(
    plan: dict[str, Any], manifest_path: str | None, settings: Settings | None = None, revision: str = ""
) -> bytes:
    """A top view (world x-y, metres) of a plan: the object's footprint and principal axes, the open hand's
    reference points at the grasp pose, the flange axes, the closure signature's axis and the approach start.

    The hand is drawn from ``manifest_path`` loaded under ``settings``; ``revision`` names that revision of the
    hand (the registry's token) and keys the planner's cache of it, so a replaced hand is never drawn stale.

    Drawn with Matplotlib (no OpenGL needed). Returns PNG bytes.
    """
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Ellipse, Polygon

    from softsig_service.geometry.transforms import Pose
    from softsig_service.objects import convex_hull_2d, object_from_json

    obj = object_from_json(plan["object"])
    fig = Figure(figsize=(7.2, 6.4), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    c = obj.center
    R = obj.pose[:3, :3]

    def world_xy(points_obj: Any) -> Any:
        return (np.asarray(points_obj) @ R.T + c)[:, :2]

    style = {"facecolor": "#d9c9a3", "edgecolor": "#6b5a33", "lw": 1.5, "alpha": 0.9, "label": "object footprint"}
    hx, hy, _ = obj.half_extents
    yaw_deg = math.degrees(obj.yaw)
    if obj.kind == "mesh":
        assert obj.vertices is not None
        hull = convex_hull_2d(obj.vertices[:, :2])
        ax.add_patch(Polygon(world_xy(np.c_[hull, np.zeros(len(hull))]), closed=True, **style))
    elif obj.kind in ("sphere", "ellipsoid") or (obj.kind == "cylinder" and obj.standing):
        ax.add_patch(Ellipse((c[0], c[1]), 2 * hx, 2 * hy, angle=yaw_deg, **style))
    else:
        corners = np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]])
        ax.add_patch(Polygon(world_xy(corners), closed=True, **style))
    reach = max(obj.extent_major, 0.08)
    for axis, name, colour in ((obj.o1, "o1 (major)", "#555555"), (obj.o2, "o2 (minor)", "#999999")):
        a, b = c[:2] - 0.6 * reach * axis[:2], c[:2] + 0.6 * reach * axis[:2]
        ax.plot([a[0], b[0]], [a[1], b[1]], ls="--", color=colour, lw=1, label=name)

    grasp = plan.get("grasp_pose")
    # poses in the plan's output frame, drawn in base_link
    frame = plan.get("output_frame_pose")
    T_frame = Pose.from_wire(frame).matrix() if frame else np.eye(4)
    if grasp is not None:
        T_flange = T_frame @ Pose.from_wire(grasp).matrix()
        T = T_frame @ Pose.from_wire(plan.get("grasp_frame_pose") or grasp).matrix()  # the hand's points are in it
        Rg, p = T[:3, :3], T[:3, 3]
        cs_axis = cs_anchor = None
        if manifest_path is not None:
            from softsig_service.planning.planner import planning_model

            solver = plan.get("solver") or {}
            method = str(solver.get("cs_method", "ellipsoid"))
            criterion: Criterion = "relative" if solver.get("cs_criterion") == "relative" else "absolute"
            model = planning_model(manifest_path, method, settings, criterion, revision)
            pts = model.points_open @ Rg.T + p
            if len(pts) >= 3:
                hull = convex_hull_2d(pts[:, :2])
                if len(hull) >= 3:
                    ax.add_patch(Polygon(hull, closed=True, facecolor="#7fa7d9", alpha=0.25, edgecolor="#2d5d9f",
                                         label="open hand (reference points)"))  # fmt: skip
            ax.scatter(pts[:, 0], pts[:, 1], s=18, color="#2d5d9f", zorder=5)
            for name, (x, y) in zip(model.point_names, pts[:, :2], strict=False):  # the reference points named
                ax.annotate(name, (x, y), textcoords="offset points", xytext=(3, 3), fontsize=6, color="#2d5d9f")
            cs_axis = Rg @ model.signature.axis
            cs_anchor = Rg @ model.signature.anchor + p
        pf = T_flange[:3, 3]
        ax.add_patch(Circle((pf[0], pf[1]), 0.004, color="black", zorder=6, label="flange (tool0)"))
        L = 0.05
        ax.annotate("", xy=(p[0] + L * Rg[0, 0], p[1] + L * Rg[1, 0]), xytext=(p[0], p[1]),
                    arrowprops={"arrowstyle": "->", "color": "#c0392b", "lw": 2})  # fmt: skip
        ax.annotate("", xy=(p[0] + L * Rg[0, 1], p[1] + L * Rg[1, 1]), xytext=(p[0], p[1]),
                    arrowprops={"arrowstyle": "->", "color": "#27ae60", "lw": 2})  # fmt: skip
        ax.plot([], [], color="#c0392b", lw=2, label="hand +x")
        ax.plot([], [], color="#27ae60", lw=2, label="hand +y")
        if cs_axis is not None and cs_anchor is not None:
            h = cs_axis[:2]
            if float(np.linalg.norm(h)) > 1e-9:
                a, b = cs_anchor[:2] - 0.07 * h, cs_anchor[:2] + 0.07 * h
                ax.plot([a[0], b[0]], [a[1], b[1]], color="#8e44ad", lw=3, label="closure signature axis")
        pre = plan.get("pre_grasp_pose")
        if pre is not None:
            q = (T_frame @ Pose.from_wire(pre).matrix())[:3, 3]
            ax.scatter([q[0]], [q[1]], marker="x", s=50, color="#e67e22", zorder=6,
                       label=f"pre-grasp (z = {q[2]:.3f} m)")  # fmt: skip
    else:
        ax.text(c[0], c[1] - 0.9 * reach, "no grasp pose", ha="center", color="#c0392b")
    span = max(0.16, 1.4 * reach)
    ax.set_xlim(c[0] - span, c[0] + span)
    ax.set_ylim(c[1] - span, c[1] + span)
    base = -c[:2]
    if float(np.linalg.norm(base)) > 1e-6:
        d = base / np.linalg.norm(base)
        tip = c[:2] + 0.9 * span * d
        start = c[:2] + 0.65 * span * d
        ax.annotate(
            "UR5 base",
            xy=(float(tip[0]), float(tip[1])),
            xytext=(float(start[0]), float(start[1])),
            ha="center",
            fontsize=8,
            arrowprops={"arrowstyle": "->", "color": "#7f8c8d"},
        )
    ax.set_aspect("equal")
    ax.grid(True, lw=0.4, alpha=0.6)
    ax.set_xlabel("x [m] (base_link)")
    ax.set_ylabel("y [m] (base_link)")
    status = "success" if plan.get("success") else "failed: " + ", ".join(plan.get("reasons") or [])
    quality = plan.get("quality") or {}
    err = quality.get("alignment_error")
    sub = f"alignment error {math.degrees(err):.2f} deg" if isinstance(err, int | float) else ""
    ax.set_title(f"{plan.get('hand')} / {obj.name or obj.kind} / strategy {plan.get('strategy')}: {status}\n{sub}",
                 fontsize=10)  # fmt: skip
    ax.legend(loc="upper right", fontsize=7, framealpha=0.85)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


# ----------------------------------------------------------------------------------------------------------
# job callables (run in a job's own process)
# ----------------------------------------------------------------------------------------------------------
