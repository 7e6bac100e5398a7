"""Offscreen pictures of a hand open and closed, side by side (MuJoCo's renderer; needs an OpenGL backend).

:func:`render_open_closed` draws two panels on a white background, "open" (left) and "closed" (right), seen by
the same orthographic camera framed so that the hand, in both postures, and the drawn axes fill the panel:

* the hand frame (docs/design.md §3; the mount body's frame after the manifest's ``mount_pose``, origin at the
  flange) as three arrows from its origin: +x red, +y green, +z (the approach) blue, each 0.6 of the open hand's
  largest extent [m] or, when the hand reaches farther along that axis, 1.15 of its reach, so its tip clears the
  hand;
* the grasp frame (the manifest's ``grasp_frame``, ``T_HG``) as three thinner arrows labelled x_G, y_G, z_G when
  it differs from the hand frame (the caption says so when they coincide);
* the closure signature's axis, when one is given, as an orange double arrow through its anchor (the CS is an
  axis: both senses are valid). A CS is computed in the grasp frame
  (:func:`softsig_service.simulation.hand_signature.hand_closure_signature`, as ``softsig signature closure``
  does) and drawn turned into the hand frame by ``T_HG``.

The axes are drawn over the rendered hand, so none of them can disappear behind it: a part of an arrow that the
hand hides (a ray from it toward the camera meets a visible geom, ``mujoco.mj_ray``) is drawn dashed, the rest
solid. The camera looks at the palm side (+z) along one of the four hand-frame directions (±1, ±1, 1)/√3, 35°
above the palm plane, so every axis appears at 82 % of its length and none is seen end on; of the four, it takes
the one from which the open hand hides the least of its least visible hand-frame axis (then the least of all
three; the first in the order (-x, -y), (+x, -y), (-x, +y), (+x, +y) on a tie). The image's up is the
hand's +z. The background is every pixel where MuJoCo's segmentation render finds no geom.

Without a GPU, MuJoCo renders through EGL (``MUJOCO_GL=egl``, Debian's ``libegl1 libegl-mesa0
libgl1-mesa-dri``) or OSMesa. When no backend can be created, :class:`RenderUnavailable` says so.
"""

from __future__ import annotations

import copy
import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import RenderUnavailable
from softsig_service.gl_backend import render_unavailable_reason
from softsig_service.hands.closure import prepare_data, run_closure
from softsig_service.hands.model import HandModel

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.patheffects import AbstractPathEffect

_AXIS_RGBA = ((0.9, 0.1, 0.1, 1.0), (0.1, 0.75, 0.1, 1.0), (0.15, 0.3, 0.95, 1.0))
# rotations that turn an arrow's own +z onto the frame's +x, +y and +z
_Z_TO_AXIS = (
    np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
    np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    np.eye(3),
)
BACKGROUND: tuple[float, float, float] = (1.0, 1.0, 1.0)
"""The panels' background colour (RGB in [0, 1])."""
CS_COLOR: tuple[float, float, float] = (1.0, 0.5, 0.0)
"""The colour of the closure signature's axis (RGB in [0, 1])."""
_VISIBLE_GROUPS = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)  # the geom groups MuJoCo's scene shows by default
# the candidate camera directions (hand frame, from the look-at point toward the camera), in tie-break order
_VIEWS = tuple(np.array([sx, sy, 1.0]) / np.sqrt(3.0) for sy in (-1.0, 1.0) for sx in (-1.0, 1.0))
_SAMPLES = 24  # points per drawn segment tested for visibility


def draw_hand_frame(scene: mujoco.MjvScene, hand: HandModel, data: mujoco.MjData, length: float) -> None:
    """Add the hand frame's axes to ``scene`` as 3-D arrows of ``length`` [m] (x red, y green, z blue)."""
    R = data.xmat[hand.mount_body].reshape(3, 3)
    origin = data.xpos[hand.mount_body]
    for rgba, turn in zip(_AXIS_RGBA, _Z_TO_AXIS, strict=True):
        if scene.ngeom >= scene.maxgeom:
            return
        mujoco.mjv_initGeom(
            scene.geoms[scene.ngeom],
            mujoco.mjtGeom.mjGEOM_ARROW,
            np.array([0.03 * length, 0.03 * length, length]),
            origin,
            (R @ turn).flatten(),
            np.array(rgba, dtype=np.float32),
        )
        scene.ngeom += 1


class DrawnSignature(Protocol):
    """What the render draws of a closure signature (a :class:`~softsig_service.signatures.ClosureSignature`):
    its unit ``axis`` and ``anchor`` [m] in the grasp frame, and the ``method`` that found it."""

    @property
    def axis(self) -> Any: ...

    @property
    def anchor(self) -> Any: ...

    @property
    def method(self) -> str: ...


@dataclass(frozen=True)
class _Segment:
    """A straight piece of the overlay between two world points [m]."""

    start: NDArray[np.float64]
    end: NDArray[np.float64]
    color: tuple[float, float, float]
    width: float
    label: str
    arrow: str  # matplotlib arrow style: "-|>" (an arrow at the end) or "<|-|>" (both ends)
    style: str = "-"


@dataclass(frozen=True)
class _View:
    """An orthographic camera: centre [m], unit vectors right, up and toward the camera (world frame), and the
    half-height of the view [m]."""

    center: NDArray[np.float64]
    right: NDArray[np.float64]
    up: NDArray[np.float64]
    back: NDArray[np.float64]
    half_height: float
    aspect: float  # width / height

    def pixels(self, points: NDArray[np.float64], width: int, height: int) -> NDArray[np.float64]:
        """(n, 2) image coordinates [px] of world points (n, 3): column from the left, row from the top."""
        rel = np.atleast_2d(points) - self.center
        u = rel @ self.right / (self.half_height * self.aspect)
        v = rel @ self.up / self.half_height
        return np.stack([(u + 1.0) * 0.5 * width, (1.0 - v) * 0.5 * height], axis=1)

    def apply(self, scene: mujoco.MjvScene) -> None:
        """Set the scene's cameras to this view (call after ``update_scene``)."""
        distance = 4.0 * self.half_height * max(1.0, self.aspect) + 1.0
        for cam in scene.camera:
            cam.pos[:] = self.center + distance * self.back
            cam.forward[:] = -self.back
            cam.up[:] = self.up
            cam.orthographic = 1
            cam.frustum_center = 0.0
            cam.frustum_width = self.half_height * self.aspect
            cam.frustum_bottom = -self.half_height
            cam.frustum_top = self.half_height
            cam.frustum_near = 0.01
            cam.frustum_far = 2.0 * distance


def _geom_corners(model: mujoco.MjModel, data: mujoco.MjData) -> NDArray[np.float64]:
    """The corners of every visible hand geom's bounding box, world frame [m] (n, 3)."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
    out = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == 0 or model.geom_group[g] > 2 or model.geom_rgba[g, 3] == 0:
            continue
        box = model.geom_aabb[g]
        local = box[:3] + signs * box[3:]
        out.append(data.geom_xpos[g] + local @ data.geom_xmat[g].reshape(3, 3).T)
    if not out:
        return np.zeros((1, 3))
    return np.concatenate(out)


def _visible(
    model: mujoco.MjModel, data: mujoco.MjData, points: NDArray[np.float64], back: NDArray[np.float64]
) -> NDArray[np.bool_]:
    """Whether each world point (n, 3) [m] is seen from direction ``back`` (no visible geom between it and the
    camera; a point inside a geom is hidden)."""
    geomid = np.zeros(1, dtype=np.int32)
    return np.array(
        [mujoco.mj_ray(model, data, p, back, _VISIBLE_GROUPS, True, -1, geomid) < 0 for p in points], dtype=bool
    )


def _along(start: NDArray[np.float64], end: NDArray[np.float64], n: int = _SAMPLES) -> NDArray[np.float64]:
    return start + np.linspace(0.0, 1.0, n)[:, None] * (end - start)


def _choose_direction(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    origin: NDArray[np.float64],
    R: NDArray[np.float64],
    length: NDArray[np.float64],
) -> NDArray[np.float64]:
    """The camera direction (world frame, toward the camera) from which the open hand hides the least of the hand
    frame's least visible axis (module docstring); ``length`` [m] per axis."""
    best, best_score = R @ _VIEWS[0], (-1.0, -1.0)
    for view in _VIEWS:
        back = R @ view
        shown = [
            float(_visible(model, data, _along(origin, origin + length[k] * R[:, k])[1:], back).mean())
            for k in range(3)
        ]
        score = (min(shown), sum(shown))
        if score > best_score:
            best, best_score = back, score
    return best


def _frame_view(
    points: NDArray[np.float64], back: NDArray[np.float64], up_hint: NDArray[np.float64], aspect: float
) -> _View:
    """An orthographic view along ``back`` with the image's up nearest ``up_hint`` that shows ``points`` (world
    [m]) in the panel, leaving bands at the top and the bottom for the panel's text."""
    up = up_hint - (up_hint @ back) * back
    up /= np.linalg.norm(up)
    right = np.cross(up, back)
    u, v = points @ right, points @ up
    half_w = 0.5 * float(np.ptp(u)) or 1e-3
    half_v = 0.5 * float(np.ptp(v)) or 1e-3
    top, bottom, side = 0.15, 0.14, 0.04  # fractions of the panel kept free of the drawing
    half_height = max(half_v / (1.0 - top - bottom), half_w / (aspect * (1.0 - 2.0 * side)))
    # the drawing's middle sits at the middle of the band between the top and the bottom margins
    v_mid = 0.5 * (v.min() + v.max()) + (top - bottom) * half_height
    u_mid = 0.5 * (u.min() + u.max())
    along = float(np.mean(points @ back))
    return _View(u_mid * right + v_mid * up + along * back, right, up, back, half_height, aspect)


def render_open_closed(
    hand: HandModel,
    *,
    width: int = 480,
    height: int = 480,
    signature: DrawnSignature | None = None,
) -> NDArray[np.uint8]:
    """An RGB image (height, 2*width, 3): the hand open (left) and closed (right), gravity off.

    ``width`` and ``height`` [px] are one panel's. ``signature`` (axis and anchor in the grasp frame, e.g. from
    :func:`~softsig_service.simulation.hand_signature.hand_closure_signature`) adds the CS axis; camera,
    background and drawn axes are described in the module docstring."""
    model = copy.copy(hand.model)
    model.opt.gravity[:] = 0.0
    model.vis.headlight.ambient[:] = 0.5
    model.vis.headlight.diffuse[:] = 0.6
    model.vis.headlight.specular[:] = 0.15
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    hint = "offscreen rendering needs an OpenGL backend: install libegl1 libegl-mesa0 libgl1-mesa-dri and set "
    hint += "MUJOCO_GL=egl (or osmesa with libosmesa6)"
    reason = render_unavailable_reason()
    if reason is not None:
        raise RenderUnavailable(f"{hint}; {reason}", field="MUJOCO_GL")
    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # MuJoCo raises plain RuntimeError/ImportError kinds for GL failures
        raise RenderUnavailable(f"{hint}; MuJoCo said: {exc}", field="MUJOCO_GL") from None
    with renderer:
        data = prepare_data(hand, model)
        R = data.xmat[hand.mount_body].reshape(3, 3).copy()
        origin = data.xpos[hand.mount_body].copy()
        corners_open = _geom_corners(model, data)
        local = (corners_open - origin) @ R  # hand frame
        # each axis 0.6 of the open hand's size, or longer so that its tip clears the hand
        length = np.maximum(0.6 * float(np.max(np.ptp(local, axis=0))), 1.15 * local.max(axis=0))
        segments = _segments(hand, origin, R, length, signature)
        back = _choose_direction(model, data, origin, R, length)
        opened_data = copy.copy(data)
        closure = hand.manifest.closure
        run_closure(hand, model, data, duration=closure.duration, settle=closure.settle)
        mujoco.mj_forward(model, data)
        # the drawn segments, lengthened a little at both ends to leave room for the labels beyond the tips
        drawn = np.concatenate([_along(s.start, s.end, 2) + [[-0.15], [0.15]] * (s.end - s.start) for s in segments])
        everything = np.concatenate([corners_open, _geom_corners(model, data), drawn])
        view = _frame_view(everything, back, R[:, 2], width / height)
        panels = [_shot(renderer, model, d, view) for d in (opened_data, data)]
        shown = [[_visible(model, d, _along(s.start, s.end), back) for s in segments] for d in (opened_data, data)]
    return _compose(hand, panels, shown, segments, view, signature)


def _segments(
    hand: HandModel,
    origin: NDArray[np.float64],
    R: NDArray[np.float64],
    length: NDArray[np.float64],
    signature: DrawnSignature | None,
) -> list[_Segment]:
    """What the overlay draws, world frame: the hand frame's axes, the grasp frame's (when it differs) and the CS
    axis (when given)."""
    colors = [rgba[:3] for rgba in _AXIS_RGBA]
    out = [
        _Segment(origin, origin + length[k] * R[:, k], colors[k], 2.6, name, "-|>")
        for k, name in enumerate(("x", "y", "z"))
    ]
    T = np.asarray(hand.grasp_frame, dtype=np.float64)
    R_WG, o_G = R @ T[:3, :3], origin + R @ T[:3, 3]
    if not np.allclose(T, np.eye(4), atol=1e-9):
        out += [
            _Segment(o_G, o_G + 0.7 * float(length.min()) * R_WG[:, k], colors[k], 1.8, f"${name}_G$", "-|>")
            for k, name in enumerate(("x", "y", "z"))
        ]
    if signature is not None:
        axis = R_WG @ np.asarray(signature.axis, dtype=np.float64)
        anchor = o_G + R_WG @ np.asarray(signature.anchor, dtype=np.float64)
        cs_half = 0.75 * float(np.min(length))
        out.append(_Segment(anchor - cs_half * axis, anchor + cs_half * axis, CS_COLOR, 2.6, "CS", "<|-|>", "-."))
    return out


def _shot(renderer: mujoco.Renderer, model: mujoco.MjModel, data: mujoco.MjData, view: _View) -> NDArray[np.uint8]:
    """One RGB render of ``data`` through ``view``, with the background (no geom) set to :data:`BACKGROUND`."""
    renderer.update_scene(data)
    view.apply(renderer.scene)
    rgb = renderer.render().copy()
    renderer.enable_segmentation_rendering()
    try:
        renderer.update_scene(data)
        view.apply(renderer.scene)
        empty = renderer.render()[..., 0] < 0
    finally:
        renderer.disable_segmentation_rendering()
    rgb[empty] = np.round(np.array(BACKGROUND) * 255).astype(np.uint8)
    return rgb


def _compose(
    hand: HandModel,
    panels: Sequence[NDArray[np.uint8]],
    shown: Sequence[Sequence[NDArray[np.bool_]]],
    segments: Sequence[_Segment],
    view: _View,
    signature: DrawnSignature | None,
) -> NDArray[np.uint8]:
    """The two renders side by side with the overlay (axes, labels, panel names, captions) drawn by matplotlib."""
    from matplotlib import patheffects
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    height, width = panels[0].shape[:2]
    dpi = 100.0
    fig = Figure(figsize=(2 * width / dpi, height / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    pt = 72.0 / dpi  # points per pixel
    big, small = max(11.0, 0.065 * height) * pt, max(7.0, 0.03 * height) * pt
    halo = [patheffects.withStroke(linewidth=3.0 * max(1.0, height / 480), foreground="white")]
    scale = max(0.6, height / 480)
    same = np.allclose(hand.grasp_frame, np.eye(4), atol=1e-9)
    captions = (
        "hand frame at the flange (x red, y green, z blue)\ndashed: hidden by the hand",
        ("grasp frame = hand frame" if same else "thin arrows: the grasp frame")
        + ("" if signature is None else f"\norange: CS axis ({signature.method}) through its anchor"),
    )
    for i, (image, title) in enumerate(zip(panels, ("open", "closed"), strict=True)):
        ax = fig.add_axes((i * 0.5, 0.0, 0.5, 1.0))
        ax.imshow(image, extent=(0, width, height, 0), interpolation="none")
        ax.set_xlim(0, width)
        ax.set_ylim(height, 0)
        ax.set_axis_off()
        for seg, visible in zip(segments, shown[i], strict=True):
            _draw_segment(ax, seg, visible, view, width, height, scale, halo, small * 1.3)
        ax.text(0.04, 0.965, title, transform=ax.transAxes, fontsize=big, fontweight="bold", va="top", ha="left")
        if i == 0:
            ax.text(0.96, 0.965, hand.name, transform=ax.transAxes, fontsize=small * 1.2, va="top", ha="right",
                    color="0.3")  # fmt: skip
        ax.text(0.5, 0.025, captions[i], transform=ax.transAxes, fontsize=small, ha="center", va="bottom",
                color="0.25", linespacing=1.3)  # fmt: skip
    fig.add_artist(Line2D([0.5, 0.5], [0.03, 0.97], color="0.75", linewidth=1.0))
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())
    out = np.full((height, 2 * width, 3), 255, dtype=np.uint8)
    h, w = min(height, rgba.shape[0]), min(2 * width, rgba.shape[1])
    out[:h, :w] = rgba[:h, :w, :3]
    return out


def _draw_segment(
    ax: Axes,
    seg: _Segment,
    visible: NDArray[np.bool_],
    view: _View,
    width: int,
    height: int,
    scale: float,
    halo: Sequence[AbstractPathEffect],
    fontsize: float,
) -> None:
    """Draw ``seg`` projected into a panel: solid where ``visible``, dashed where the hand hides it, its arrow
    head(s) and its label beyond its end."""
    px = view.pixels(_along(seg.start, seg.end), width, height)
    lw = seg.width * scale
    # runs of equal visibility, each drawn from its first sample to the next run's first
    changes = [k for k in range(1, len(visible)) if visible[k] != visible[k - 1]]
    edges = sorted({0, *changes, len(visible) - 1})
    for a, b in itertools.pairwise(edges):
        style = seg.style if visible[a] else (0, (2.0, 2.0))
        ax.plot(px[a : b + 1, 0], px[a : b + 1, 1], color=seg.color, linewidth=lw, linestyle=style,
                solid_capstyle="butt", path_effects=halo)  # fmt: skip
    head = 10.0 * scale
    tip, before = px[-1], px[-3]
    ax.annotate("", xy=tuple(tip), xytext=tuple(before),
                arrowprops={"arrowstyle": f"-|>,head_length={0.06 * head},head_width={0.035 * head}",
                            "color": seg.color, "linewidth": lw, "shrinkA": 0, "shrinkB": 0})  # fmt: skip
    if seg.arrow == "<|-|>":
        ax.annotate("", xy=tuple(px[0]), xytext=tuple(px[2]),
                    arrowprops={"arrowstyle": f"-|>,head_length={0.06 * head},head_width={0.035 * head}",
                                "color": seg.color, "linewidth": lw, "shrinkA": 0, "shrinkB": 0})  # fmt: skip
    direction = tip - px[0]
    norm = float(np.linalg.norm(direction))
    offset = direction / norm * (1.1 * fontsize / 0.72) if norm > 1e-6 else np.zeros(2)
    ax.text(tip[0] + offset[0], tip[1] + offset[1], seg.label, color=seg.color, fontsize=fontsize,
            fontweight="bold", ha="center", va="center", path_effects=halo)  # fmt: skip


def save_png(image: NDArray[np.uint8], path: Path) -> None:
    """Write an RGB image to ``path`` as PNG."""
    import matplotlib.image

    path.parent.mkdir(parents=True, exist_ok=True)
    matplotlib.image.imsave(path, image)
