"""A keyframe strip per trial: the scene at the end of each phase of the rollout, side by side in one picture.

:class:`KeyframeRecorder` is the rollout's :class:`~softsig_service.simulation.rollout.PhaseObserver`: at the start
of a simulated trial it fixes one camera for the whole trial, and at the end of each phase (approach, closure, lift,
hold; or the early stop, ``stopped``: where :func:`softsig_service.simulation.diagnosis.snapshot` is taken) it
renders the scene offscreen (``mujoco.Renderer``, needs an OpenGL backend) and keeps the contact forces on the
object. :meth:`KeyframeRecorder.save` composes the panels (matplotlib) into one PNG:

* one panel of :data:`PANEL_SIZE` per phase boundary reached, left to right, each labelled with the phase, the
  simulated time [s], the hand bodies touching the object with the normal force each presses on it [N] and the
  object's height above the table [mm];
* the contact forces on the object as arrows drawn over the render (never hidden by a finger), head at the contact
  point, pointing along the force [N] the hand (red) or the table and anything else (grey) exerts on the object,
  one scale [mm per N, in the scene] for the whole strip (its largest force as long as a third of the view's
  height at the object), stated in the title band;
* a title band on top: the trial's label and outcome, the diagnosis summary line
  (:func:`softsig_service.simulation.diagnosis.summary`, as ``softsig validate`` prints it) and the arrows' scale.

The camera (world frame, UR5 ``base_link``, z up) is a MuJoCo free camera: elevation :data:`ELEVATION` [deg]
(looking down), the azimuth (every 15°) from which the open hand at the grasp pose spreads widest across the view
(broadside to its fingers), on the far side of the object from the arm's base (the arm behind the hand), looking at
the middle of the boxes of the object at its start and raised by the lift and of the hand at the pre-grasp, the
grasp and the top of the lift, as close as keeps all of them in view. A trial that simulated nothing (a failed
plan) gets one grey panel saying so.

Cost: only a trial given a recorder renders (``on_phase`` of :func:`softsig_service.simulation.rollout.simulate`);
one render per phase boundary plus one matplotlib composition per trial (docs/validation.md states the
figures).
"""

from __future__ import annotations

import copy
import math
import textwrap
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import RenderUnavailable
from softsig_service.gl_backend import render_unavailable_reason
from softsig_service.simulation.diagnosis import NO_FORCE, object_contacts, summary
from softsig_service.simulation.scene_model import GEOM_HAND, Scene

FloatArray = NDArray[np.float64]

PANEL_SIZE = (400, 400)
"""Width and height [px] of one panel (one phase boundary)."""
TITLE_HEIGHT = 112
"""[px] height of the title band above the panels."""
ELEVATION = -18.0
"""[deg] the camera's elevation (negative: looking down)."""
AZIMUTH_STEP = 15.0
"""[deg] step of the azimuths tried for the camera."""
MARGIN = (0.06, 0.16)
"""Fractions of a panel's width (each side) and height (top and bottom) kept free of the framed boxes (room for
the labels)."""
HAND_FORCE_RGB = (0.85, 0.1, 0.1)
OTHER_FORCE_RGB = (0.35, 0.35, 0.35)
SHADOW_SIZE = 2048
"""[px] side of the shadow map the panels are rendered with (MuJoCo's default, 4096, takes 4 times as long on a
software renderer for no difference a 400 px panel shows)."""
FORCE_VIEW_FRACTION = 1.0 / 3.0
"""The strip's largest force is drawn this fraction of the view's height at the object long."""

_CORNER_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)


def geom_corners(model: mujoco.MjModel, data: mujoco.MjData, geoms: NDArray[np.integer[Any]]) -> FloatArray:
    """The corners of the bounding boxes (``geom_aabb``, each in its geom's frame) of ``geoms`` as posed in
    ``data``: (8 n, 3), world frame [m]."""
    geoms = np.asarray(geoms, dtype=np.int64)
    if geoms.size == 0:
        return np.zeros((0, 3))
    aabb = model.geom_aabb[geoms]
    local = aabb[:, None, :3] + _CORNER_SIGNS[None] * aabb[:, None, 3:]  # (n, 8, 3), geom frames
    R = data.geom_xmat[geoms].reshape(-1, 3, 3)
    world = np.einsum("gij,gkj->gki", R, local) + data.geom_xpos[geoms][:, None, :]
    return np.asarray(world.reshape(-1, 3), dtype=np.float64)


@dataclass(frozen=True)
class Camera:
    """A MuJoCo free camera: it looks at ``lookat`` [m] (world) from ``distance`` [m] along the direction given by
    ``azimuth`` and ``elevation`` [deg] (MuJoCo's convention: forward = (cos e cos a, cos e sin a, sin e)), with a
    vertical field of view ``fovy`` [deg]."""

    lookat: FloatArray
    distance: float
    azimuth: float
    elevation: float
    fovy: float

    def basis(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Unit vectors right, up and forward (into the view) of the image, world frame."""
        return _basis(self.azimuth, self.elevation)

    def mjv(self) -> mujoco.MjvCamera:
        """This camera as an ``mjvCamera`` for ``mujoco.Renderer.update_scene``."""
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance = self.distance
        cam.azimuth = self.azimuth
        cam.elevation = self.elevation
        return cam

    def pixels(self, points: FloatArray, width: int, height: int) -> FloatArray:
        """(n, 2) image coordinates [px] (column from the left, row from the top) of world points (n, 3) [m]."""
        right, up, forward = self.basis()
        rel = np.atleast_2d(points) - (self.lookat - self.distance * forward)
        depth = np.maximum(rel @ forward, 1e-9)
        f = 0.5 * height / math.tan(math.radians(0.5 * self.fovy))
        return np.stack([0.5 * width + f * (rel @ right) / depth, 0.5 * height - f * (rel @ up) / depth], axis=1)

    def view_height(self) -> float:
        """[m] the height of the view in the plane through ``lookat``."""
        return 2.0 * self.distance * math.tan(math.radians(0.5 * self.fovy))


def _basis(azimuth: float, elevation: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    a, e = math.radians(azimuth), math.radians(elevation)
    forward = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    right = np.array([math.sin(a), -math.cos(a), 0.0])
    return right, np.cross(right, forward), forward


def choose_azimuth(hand_points: FloatArray, towards: FloatArray) -> float:
    """[deg] the azimuth (every :data:`AZIMUTH_STEP`) across which ``hand_points`` (world [m]) spread widest, of
    the two opposite ones the one whose view points toward ``towards`` (world [m], e.g. the arm's base) seen from
    the points' middle; the first on a tie."""
    centre = 0.5 * (hand_points.min(axis=0) + hand_points.max(axis=0))
    to_base = np.asarray(towards, dtype=np.float64)[:2] - centre[:2]
    best, best_width = 0.0, -1.0
    for azimuth in np.arange(0.0, 180.0, AZIMUTH_STEP):
        right, _, _ = _basis(float(azimuth), 0.0)
        width = float(np.ptp(hand_points @ right))
        if width > best_width + 1e-9:
            best, best_width = float(azimuth), width
    _, _, forward = _basis(best, 0.0)
    return best if float(forward[:2] @ to_base) >= 0.0 else best + 180.0


def frame_camera(points: FloatArray, azimuth: float, elevation: float, fovy: float, aspect: float) -> Camera:
    """The camera at ``azimuth`` and ``elevation`` [deg] looking at the middle of ``points`` (world [m]) from as
    close as keeps every point inside the view less :data:`MARGIN`; ``aspect`` = width / height."""
    right, up, forward = _basis(azimuth, elevation)
    lookat = 0.5 * (points.min(axis=0) + points.max(axis=0))
    rel = points - lookat
    t_y = math.tan(math.radians(0.5 * fovy)) * (1.0 - 2.0 * MARGIN[1])
    t_x = math.tan(math.radians(0.5 * fovy)) * aspect * (1.0 - 2.0 * MARGIN[0])
    x, y, z = np.abs(rel @ right), np.abs(rel @ up), rel @ forward
    distance = float(max(np.max(x / t_x - z), np.max(y / t_y - z), 0.05))
    return Camera(lookat, distance, azimuth, elevation, fovy)


@dataclass(frozen=True)
class ContactArrow:
    """A contact on the object: its point [m] and the force [N] exerted on the object there (world frame), and
    whether the hand exerts it."""

    point: FloatArray
    force: FloatArray
    from_hand: bool


def object_contact_forces(scene: Scene, data: mujoco.MjData) -> list[ContactArrow]:
    """Every penetrating contact (distance <= 0) of the object with anything: the force on the object [N] (normal
    and friction, ``mj_contactForce`` turned into the world frame) at the contact point [m]."""
    out = []
    f6 = np.zeros(6)
    for i, other, object_first in object_contacts(scene, data):
        con = data.contact[i]
        mujoco.mj_contactForce(scene.model, data, i, f6)
        force = con.frame.reshape(3, 3).T @ f6[:3]  # on geom2, from geom1 (the normal points from geom1 to geom2)
        on_object = -force if object_first else force
        hand = bool(scene.geom_class[other] == GEOM_HAND)
        out.append(ContactArrow(np.array(con.pos, dtype=np.float64), on_object, hand))
    return out


class TrialOutcome(Protocol):
    """What a strip's title needs of a trial (a :class:`~softsig_service.experiments.trial.TrialResult`)."""

    @property
    def seed(self) -> int: ...
    @property
    def success(self) -> bool: ...
    @property
    def reason(self) -> str | None: ...
    @property
    def diagnosis(self) -> Mapping[str, Any]: ...


@dataclass
class Panel:
    """One phase boundary: the render (height, width, 3), its diagnosis snapshot and the contact forces."""

    image: NDArray[np.uint8]
    snapshot: Mapping[str, Any]
    arrows: list[ContactArrow] = field(default_factory=list)


class KeyframeRecorder:
    """Renders a trial at its phase boundaries and writes the strip (module docstring).

    Pass it as ``on_phase`` to :func:`~softsig_service.experiments.trial.run_trial`, then call :meth:`save` after
    each trial (it starts the next one empty) and :meth:`close` at the end. Raises :class:`RenderUnavailable` when
    no OpenGL backend can render offscreen.
    """

    def __init__(self, panel_size: tuple[int, int] = PANEL_SIZE) -> None:
        reason = render_unavailable_reason()
        if reason is not None:
            raise RenderUnavailable(
                "keyframes need an OpenGL backend (MUJOCO_GL=egl with libegl1, or osmesa): " + reason, field="MUJOCO_GL"
            )
        self.width, self.height = panel_size
        self.panels: list[Panel] = []
        self.camera: Camera | None = None
        self.seconds = 0.0
        """[s] wall time spent framing, rendering, composing and writing, over every trial so far."""
        self._renderer: mujoco.Renderer | None = None
        self._model: mujoco.MjModel | None = None

    # -- the rollout's PhaseObserver ------------------------------------------------------------------------

    def start(self, scene: Scene, data: mujoco.MjData, arm_poses: Sequence[FloatArray]) -> None:
        """Fix the trial's camera from the trial's first state and the arm's joint positions [rad] at the
        pre-grasp, the grasp and the top of the lift (in that order)."""
        t0 = time.perf_counter()
        self.panels = []
        model = scene.model
        scratch = copy.copy(data)
        hand, flange_z = [], []
        for q in arm_poses:
            scratch.qpos[scene.arm_qpos] = q
            mujoco.mj_kinematics(model, scratch)
            hand.append(geom_corners(model, scratch, scene.hand_geoms))
            flange_z.append(float(scratch.xpos[scene.flange_body][2]))
        obj = geom_corners(model, data, scene.object_geoms)
        rise = np.array([0.0, 0.0, max(flange_z[-1] - flange_z[min(1, len(flange_z) - 1)], 0.0)])
        points = np.concatenate([obj, obj + rise, *hand])
        azimuth = choose_azimuth(hand[min(1, len(hand) - 1)], np.zeros(3))
        self.camera = frame_camera(points, azimuth, ELEVATION, float(model.vis.global_.fovy), self.width / self.height)
        if self._renderer is None or self._model is not model:
            self._open(model)
        self.seconds += time.perf_counter() - t0

    def phase_end(self, scene: Scene, data: mujoco.MjData, snapshot: Mapping[str, Any]) -> None:
        """Render the scene at the end of a phase (``snapshot``: its diagnosis) and keep its contact forces."""
        assert self._renderer is not None and self.camera is not None, "start() comes first"
        t0 = time.perf_counter()
        self._renderer.update_scene(data, camera=self.camera.mjv())
        image = self._renderer.render().copy()
        self.panels.append(Panel(image, dict(snapshot), object_contact_forces(scene, data)))
        self.seconds += time.perf_counter() - t0

    # -- the strip -------------------------------------------------------------------------------------------

    def _open(self, model: mujoco.MjModel) -> None:
        """A renderer for ``model``: of a copy with a panel-sized buffer and a :data:`SHADOW_SIZE` shadow map."""
        if self._renderer is not None:
            self._renderer.close()
        seen = copy.copy(model)
        seen.vis.global_.offwidth = max(int(model.vis.global_.offwidth), self.width)
        seen.vis.global_.offheight = max(int(model.vis.global_.offheight), self.height)
        seen.vis.quality.shadowsize = min(int(model.vis.quality.shadowsize), SHADOW_SIZE)
        try:
            self._renderer = mujoco.Renderer(seen, height=self.height, width=self.width)
        except Exception as exc:  # MuJoCo raises plain RuntimeError kinds for GL failures
            raise RenderUnavailable(f"cannot create an offscreen renderer: {exc}", field="MUJOCO_GL") from None
        self._model = model

    def compose(self, label: str, success: bool, reason: str | None, diagnosis: Mapping[str, Any]) -> NDArray[np.uint8]:
        """The strip of the panels recorded since the last :meth:`start`, as an RGB image (``TITLE_HEIGHT`` +
        panel height, panels x panel width, 3), titled ``label`` and the outcome (``success``, else the failure's
        ``reason``); one grey panel when there are none."""
        headline = f"{label}: " + ("success" if success else f"FAILED: {reason}")
        return compose_strip(self.panels, self.camera, headline, diagnosis, (self.width, self.height))

    def save(self, path: Path, label: str, success: bool, reason: str | None, diagnosis: Mapping[str, Any]) -> Path:
        """Write the strip (:meth:`compose`) to ``path`` as PNG and forget the panels; returns ``path``."""
        from PIL import Image  # Pillow comes with matplotlib

        t0 = time.perf_counter()
        image = self.compose(label, success, reason, diagnosis)
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(image).save(path, compress_level=3)
        self.panels, self.camera = [], None
        self.seconds += time.perf_counter() - t0
        return path

    def save_trial(self, folder: Path, k: int, trial: TrialOutcome, setting: str) -> Path:
        """Write the strip of trial ``k`` to ``folder/trial_NNN.png`` (:meth:`save`), titled ``setting`` (hand,
        object, strategy), the trial's index and seed, and its outcome."""
        label = f"{setting} / trial {k}, seed {trial.seed}"
        return self.save(folder / f"trial_{k:03d}.png", label, trial.success, trial.reason, trial.diagnosis)

    def close(self) -> None:
        """Release the renderer."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = self._model = None


def phase_label(snapshot: Mapping[str, Any]) -> str:
    """The title of a panel: the phase it ends and the simulated time [s]."""
    phase = str(snapshot["phase"])
    name = "stopped early" if phase == "stopped" else f"end of {phase}"
    return f"{name}, t = {float(snapshot['time']):.2f} s"


def panel_caption(snapshot: Mapping[str, Any]) -> str:
    """The caption of a panel: the hand bodies touching the object with their normal forces [N], and where the
    object is."""
    contacts: Mapping[str, float] = snapshot.get("hand_contacts", {})
    hand = ", ".join(f"{k} {v:.1f} N" for k, v in contacts.items()) if contacts else "none"
    where = "on the table" if snapshot.get("touches_table") else f"{float(snapshot['height']) * 1000:.0f} mm up"
    return textwrap.fill(f"hand contacts: {hand}", 58) + f"\nobject {where}"


def force_scale(panels: Sequence[Panel], camera: Camera | None) -> float:
    """[m per N] the arrows' scale: the strip's largest force (at least 1 N) drawn :data:`FORCE_VIEW_FRACTION`
    of the view's height at the object long, rounded down to 1, 2 or 5 times a power of ten [mm per N]."""
    forces = [float(np.linalg.norm(a.force)) for p in panels for a in p.arrows]
    largest = max([1.0, *forces])
    height = camera.view_height() if camera is not None else 0.3
    mm_per_n = FORCE_VIEW_FRACTION * height * 1000.0 / largest
    power = 10.0 ** math.floor(math.log10(mm_per_n))
    nice = max(m for m in (1.0, 2.0, 5.0) if m * power <= mm_per_n * (1 + 1e-9))
    return nice * power / 1000.0


def compose_strip(
    panels: Sequence[Panel],
    camera: Camera | None,
    headline: str,
    diagnosis: Mapping[str, Any],
    panel_size: tuple[int, int] = PANEL_SIZE,
) -> NDArray[np.uint8]:
    """The panels side by side under a title band (module docstring): an RGB image of height
    ``TITLE_HEIGHT + panel_size[1]`` and width ``max(1, len(panels)) * panel_size[0]`` [px]."""
    from matplotlib import patheffects
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    width, height = panel_size
    n = max(1, len(panels))
    total_w, total_h = n * width, height + TITLE_HEIGHT
    dpi = 100.0
    pt = 72.0 / dpi  # points per pixel
    fig = Figure(figsize=(total_w / dpi, total_h / dpi), dpi=dpi, facecolor="white")
    canvas = FigureCanvasAgg(fig)
    halo = [patheffects.withStroke(linewidth=3.0, foreground="white")]
    scale = force_scale(panels, camera)
    band = TITLE_HEIGHT / total_h
    chars = max(40, int(total_w / (12.5 * 0.56)))
    lines = textwrap.wrap(summary(diagnosis), chars) or [""]
    if len(lines) > 3:
        lines = [*lines[:2], textwrap.shorten(" ".join(lines[2:]), chars, placeholder=" ...")]
    fig.text(0.01, 1.0 - 8 / total_h, headline, fontsize=16 * pt, fontweight="bold", va="top", ha="left")
    fig.text(0.01, 1.0 - 34 / total_h, "\n".join(lines), fontsize=12.5 * pt, va="top", ha="left", color="0.2",
             linespacing=1.25)  # fmt: skip
    legend = (
        f"arrows: contact forces on the object, {scale * 1000:g} mm per N "
        "(red: the hand's, grey: the table's and others')"
    )
    fig.text(0.01, 1.0 - (TITLE_HEIGHT - 6) / total_h, legend, fontsize=11 * pt, va="bottom", ha="left", color="0.35")
    for i in range(n):
        ax = fig.add_axes((i / n, 0.0, 1.0 / n, 1.0 - band))
        ax.set_xlim(0, width)
        ax.set_ylim(height, 0)
        ax.set_axis_off()
        if not panels:
            ax.imshow(np.full((height, width, 3), 0.85), extent=(0, width, height, 0))
            ax.text(0.5, 0.5, "nothing simulated", transform=ax.transAxes, ha="center", va="center",
                    fontsize=15 * pt, color="0.3")  # fmt: skip
            continue
        panel = panels[i]
        ax.imshow(panel.image, extent=(0, width, height, 0), interpolation="none")
        if camera is not None:
            _draw_arrows(ax, panel.arrows, camera, scale, width, height)
        ax.text(0.03, 0.975, phase_label(panel.snapshot), transform=ax.transAxes, fontsize=15 * pt,
                fontweight="bold", va="top", ha="left", path_effects=halo)  # fmt: skip
        ax.text(0.03, 0.02, panel_caption(panel.snapshot), transform=ax.transAxes, fontsize=11.5 * pt,
                va="bottom", ha="left", color="0.1", linespacing=1.25, path_effects=halo)  # fmt: skip
    for i in range(1, n):
        fig.add_artist(Line2D([i / n, i / n], [0.0, 1.0 - band], color="white", linewidth=2.0))
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())
    out = np.full((total_h, total_w, 3), 255, dtype=np.uint8)
    h, w = min(total_h, rgba.shape[0]), min(total_w, rgba.shape[1])
    out[:h, :w] = rgba[:h, :w, :3]
    return out


def _draw_arrows(
    ax: Any, arrows: Sequence[ContactArrow], camera: Camera, scale: float, width: int, height: int
) -> None:
    """The forces on the object as arrows ending at their contact points, ``scale`` [m per N] long in the scene,
    outlined in white (seen on any colour)."""
    from matplotlib import patheffects
    from matplotlib.patches import FancyArrowPatch

    outline = [patheffects.withStroke(linewidth=4.0, foreground="white")]
    for arrow in arrows:
        if float(np.linalg.norm(arrow.force)) < NO_FORCE:
            continue
        tail, head = camera.pixels(np.stack([arrow.point - scale * arrow.force, arrow.point]), width, height)
        color = HAND_FORCE_RGB if arrow.from_hand else OTHER_FORCE_RGB
        ax.add_patch(
            FancyArrowPatch(
                tuple(tail),
                tuple(head),
                arrowstyle="-|>,head_length=7,head_width=3.5",
                color=color,
                linewidth=2.0,
                shrinkA=0,
                shrinkB=0,
                path_effects=outline,
            )
        )
