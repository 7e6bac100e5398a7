"""Offscreen pictures of a hand open and closed, side by side (MuJoCo's renderer; needs an OpenGL backend).

Both views draw the hand frame (docs/design.md §3; the mount body's frame after the manifest's ``mount_pose``) as three
arrows from its origin: +x red, +y green, +z (the approach) blue.

Without a GPU, MuJoCo renders through EGL (``MUJOCO_GL=egl``, Debian's ``libegl1 libegl-mesa0
libgl1-mesa-dri``) or OSMesa. When no backend can be created, :class:`RenderUnavailable` says so.
"""

from __future__ import annotations

import copy
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import RenderUnavailable
from softsig_service.gl_backend import render_unavailable_reason
from softsig_service.hands.closure import prepare_data, run_closure
from softsig_service.hands.model import HandModel


def _camera(model: mujoco.MjModel, data: mujoco.MjData) -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0]
    pts = data.geom_xpos[geoms]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    cam.lookat[:] = (lo + hi) / 2
    cam.distance = 1.6 * float(np.linalg.norm(hi - lo)) + 0.08
    cam.azimuth = 120.0  # looking at the palm side (+y) and the thumb
    cam.elevation = -20.0
    return cam


_AXIS_RGBA = ((0.9, 0.1, 0.1, 1.0), (0.1, 0.75, 0.1, 1.0), (0.15, 0.3, 0.95, 1.0))
# rotations that turn an arrow's own +z onto the frame's +x, +y and +z
_Z_TO_AXIS = (
    np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
    np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    np.eye(3),
)


def draw_hand_frame(scene: mujoco.MjvScene, hand: HandModel, data: mujoco.MjData, length: float) -> None:
    """Add the hand frame's axes to ``scene`` as arrows of ``length`` [m] (x red, y green, z blue)."""
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


def render_open_closed(hand: HandModel, *, width: int = 480, height: int = 480) -> NDArray[np.uint8]:
    """An RGB image (height, 2*width, 3): the hand open (left) and closed (right), gravity off."""
    model = copy.copy(hand.model)
    model.opt.gravity[:] = 0.0
    model.vis.headlight.ambient[:] = 0.45
    model.vis.headlight.diffuse[:] = 0.7
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
        cam = _camera(model, data)
        length = 0.35 * cam.distance
        renderer.update_scene(data, camera=cam)
        draw_hand_frame(renderer.scene, hand, data, length)
        opened = renderer.render().copy()
        closure = hand.manifest.closure
        run_closure(hand, model, data, duration=closure.duration, settle=closure.settle)
        renderer.update_scene(data, camera=cam)
        draw_hand_frame(renderer.scene, hand, data, length)
        closed = renderer.render().copy()
    return np.concatenate([opened, closed], axis=1)


def save_png(image: NDArray[np.uint8], path: Path) -> None:
    """Write an RGB image to ``path`` as PNG."""
    import matplotlib.image

    path.parent.mkdir(parents=True, exist_ok=True)
    matplotlib.image.imsave(path, image)
