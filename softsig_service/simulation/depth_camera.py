"""A simulated depth camera: MuJoCo renders the depth a camera at a stated pose sees of a tabletop, and the image is
back-projected to a point cloud in the camera's optical frame, as a robot's depth camera driver publishes it.

The camera is RealSense D435-like (approximate): 640 x 480 pixels, square, vertical field of view 58 degrees (the
D435's depth FOV is 87 x 58 degrees at 16:9; at 4:3 with square pixels the horizontal FOV is then 71 degrees),
range 0.1-3 m. Depth noise is Gaussian with a standard deviation growing with the square of the depth, as stereo
depth error does: ``sigma(z) = noise_at_0_6m * (z / 0.6 m)^2``, 1.5 mm at 0.6 m by default (approximate: of the
order of the D435's published sub-2% RMS error; set 0 for exact depth).

Frames: the optical frame is REP 103's (``*_optical_frame``: z forward, x right, y down); its pose is given as
``T_base_link_optical``. MuJoCo's cameras look along their -z with y up: the two differ by a half turn about x.
Units: metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput
from softsig_service.objects import TableObject

FloatArray = NDArray[np.float64]

OPTICAL_TO_MUJOCO = np.diag([1.0, -1.0, -1.0])
"""Rotation from the optical frame (z forward, y down) to MuJoCo's camera frame (-z forward, y up)."""
TABLE_HALF_SIZE = (1.5, 1.5)
"""Half-sizes [m] of the rendered table top (larger than any view of it at the camera's range)."""


@dataclass(frozen=True)
class DepthCamera:
    """Pinhole intrinsics and noise of a depth camera: ``width`` x ``height`` pixels, vertical field of view
    ``fovy`` [rad], valid range ``near``-``far`` [m], depth noise ``noise_at_0_6m`` [m] (module docstring)."""

    width: int = 640
    height: int = 480
    fovy: float = math.radians(58.0)
    near: float = 0.1
    far: float = 3.0
    noise_at_0_6m: float = 0.0015

    @property
    def focal(self) -> float:
        """Focal length [pixels] (square pixels: fx = fy)."""
        return 0.5 * self.height / math.tan(0.5 * self.fovy)

    @property
    def matrix(self) -> FloatArray:
        """The 3x3 intrinsic matrix K, principal point at the image centre, pixel centres at whole numbers (ROS and
        OpenCV: cx = (width - 1) / 2)."""
        f = self.focal
        return np.array([[f, 0.0, 0.5 * (self.width - 1)], [0.0, f, 0.5 * (self.height - 1)], [0.0, 0.0, 1.0]])


def look_at(eye: Sequence[float], target: Sequence[float]) -> FloatArray:
    """``T_base_link_optical`` (4x4) of a camera at ``eye`` [m] whose optical axis points at ``target`` [m], with
    the image's down direction (optical y) as close to world -z as the view allows."""
    e, t = np.asarray(eye, dtype=np.float64), np.asarray(target, dtype=np.float64)
    z = t - e
    if np.linalg.norm(z) < 1e-9:
        raise InvalidInput("the camera cannot look at its own position", field="target")
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 0.0, -1.0], z)  # so that y = z x x points down
    if np.linalg.norm(x) < 1e-9:  # looking straight down or up: image x along world x
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = e
    return T


def render_depth(
    objects: Sequence[TableObject], T_base_optical: FloatArray, camera: DepthCamera | None = None, *,
    table_height: float = 0.0, seed: int = 0,
) -> FloatArray:  # fmt: skip
    """The depth image ``(height, width)`` [m] (0 where nothing is within range) of ``objects`` on the table top at
    ``table_height``, seen from ``T_base_optical``; noise per the camera, drawn from ``seed``."""
    from softsig_service.gl_backend import prepare_mujoco, render_unavailable_reason

    prepare_mujoco()
    import mujoco

    from softsig_service.geometry.quaternions import matrix_to_quat
    from softsig_service.simulation.object_geom import set_object_shape

    reason = render_unavailable_reason()
    if reason is not None:
        raise RuntimeError(f"depth rendering is unavailable: {reason}")
    cam = camera or DepthCamera()
    spec = mujoco.MjSpec()
    spec.visual.global_.offwidth = max(cam.width, 640)
    spec.visual.global_.offheight = max(cam.height, 480)
    spec.stat.extent = 1.0
    spec.visual.map.znear = cam.near  # relative to the extent of 1 m
    spec.visual.map.zfar = cam.far * 2.0
    world = spec.worldbody
    table = world.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[*TABLE_HALF_SIZE, 0.01])
    table.pos = [0.0, 0.0, table_height - 0.01]
    for k, obj in enumerate(objects):
        body = world.add_body(name=f"object_{k}")
        T = obj.primitive_pose
        body.pos = T[:3, 3].tolist()
        body.quat = matrix_to_quat(T[:3, :3]).tolist()
        geom = body.add_geom()
        set_object_shape(spec, geom, obj.primitive(), f"object_{k}_mesh")
    R = np.asarray(T_base_optical, dtype=np.float64)[:3, :3] @ OPTICAL_TO_MUJOCO
    world.add_camera(name="depth", pos=np.asarray(T_base_optical)[:3, 3].tolist(), quat=matrix_to_quat(R).tolist(),
                     fovy=math.degrees(cam.fovy))  # fmt: skip
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    renderer = mujoco.Renderer(model, height=cam.height, width=cam.width)
    try:
        renderer.enable_depth_rendering()
        renderer.update_scene(data, camera="depth")
        depth = np.array(renderer.render(), dtype=np.float64)
    finally:
        renderer.close()
    if cam.noise_at_0_6m > 0.0:
        depth = (
            depth + np.random.default_rng(seed).normal(0.0, 1.0, depth.shape) * cam.noise_at_0_6m * (depth / 0.6) ** 2
        )
    depth[(depth < cam.near) | (depth > cam.far)] = 0.0
    return depth


def depth_to_points(depth: FloatArray, camera: DepthCamera | None = None, stride: int = 1) -> FloatArray:
    """The cloud ``(N, 3)`` [m] in the optical frame of the valid pixels of ``depth`` (every ``stride``-th row and
    column): pixel (u, v) at depth d is ``((u + 0.5 - cx) d / f, (v + 0.5 - cy) d / f, d)``."""
    cam = camera or DepthCamera()
    d = np.asarray(depth, dtype=np.float64)[::stride, ::stride]
    v, u = np.mgrid[0 : depth.shape[0] : stride, 0 : depth.shape[1] : stride]
    valid = d > 0.0
    f = cam.focal
    x = (u[valid] + 0.5 - 0.5 * cam.width) * d[valid] / f
    y = (v[valid] + 0.5 - 0.5 * cam.height) * d[valid] / f
    return np.column_stack([x, y, d[valid]])
