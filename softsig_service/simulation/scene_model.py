"""The validation scene as compiled: :class:`Scene` (the MuJoCo model of UR5 + hand + table + object, with the
indices of its parts) and what it reports (contacts, the object's pose in the flange frame). World frame: the UR5
``base_link``, z up; SI units. Built by :func:`softsig_service.simulation.scene.build_scene`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import NamedTuple

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.geometry.quaternions import matrix_to_quat
from softsig_service.hands.model import HandModel

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

HAND_PREFIX = "hand/"
"""Prefix of every name of the attached hand (bodies, joints, geoms, actuators, ...)."""
OBJECT_BODY = "object"
TABLE_GEOM = "table"

ARM_KP: tuple[float, ...] = (6000.0, 6000.0, 4000.0, 1500.0, 1500.0, 1500.0)
"""Position gains of the arm's joint servos [N·m/rad] (shoulder pan, shoulder lift, elbow, wrists 1-3)."""
ARM_KV: tuple[float, ...] = (300.0, 300.0, 200.0, 40.0, 40.0, 40.0)
"""Velocity (damping) gains of the arm's joint servos [N·m·s/rad]."""
ARM_ARMATURE: tuple[float, ...] = (0.5, 0.5, 0.3, 0.05, 0.05, 0.05)
"""Reflected rotor inertia of the arm's joints [kg·m²] (harmonic drives; keeps the stiff servos stable)."""
ARM_FORCE_LIMIT: tuple[float, ...] = (150.0, 150.0, 150.0, 28.0, 28.0, 28.0)
"""Servo torque limits [N·m]: the URDF's effort limits."""

ENV_BIT = 1
"""Contact bit of the environment (table, object); the hands' geoms have it in their ``conaffinity``."""
ARM_BIT = 1 << 20
"""Contact bit of the arm's geoms (collide with table and object only)."""

TABLE_FRICTION = 0.5
"""Sliding friction of the table top (MuJoCo uses the larger of the two geoms' coefficients)."""
TABLE_HALF_SIZE: tuple[float, float] = (0.9, 0.9)
"""Half-sizes [m] of the table top as drawn (centred at x = 0.3 m). For contacts it is the infinite plane
z = ``table_height`` (cheaper than a box; every reachable object lies on it)."""
GEOM_OTHER, GEOM_OBJECT, GEOM_HAND, GEOM_ARM, GEOM_TABLE, GEOM_OBSTACLE = 0, 1, 2, 3, 4, 5
"""Geom classes of :attr:`Scene.geom_class`."""
OBJECT_TORSIONAL_FRICTION = 0.005
"""[m] torsional friction of the object (``condim = 4``)."""
OBJECT_ROLLING_FRICTION = 0.0001
"""[m] rolling friction of the object."""


class ContactSummary(NamedTuple):
    """Which pairs touch: the object and the hand, an arm link and the table, an arm link and the object, an arm
    link and an obstacle, the object and the table."""

    object_hand: bool
    arm_table: bool
    arm_object: bool
    arm_obstacle: bool = False
    object_table: bool = False


_PAIRS: tuple[tuple[int, int], ...] = (
    (GEOM_OBJECT, GEOM_HAND),
    (GEOM_ARM, GEOM_TABLE),
    (GEOM_ARM, GEOM_OBJECT),
    (GEOM_ARM, GEOM_OBSTACLE),
    (GEOM_OBJECT, GEOM_TABLE),
)
"""The geom-class pairs of :class:`ContactSummary`, in its field order."""


def _pair_bits() -> NDArray[np.uint8]:
    """Per (class, class): the bit of its :data:`_PAIRS` entry (0 for a pair nobody asks about)."""
    n = GEOM_OBSTACLE + 1
    bits = np.zeros((n, n), dtype=np.uint8)
    for k, (a, b) in enumerate(_PAIRS):
        bits[a, b] = bits[b, a] = 1 << k
    return bits


_PAIR_BITS = _pair_bits()

BAD_STATE_WARNINGS: tuple[int, ...] = tuple(
    int(w)
    for w in (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL)
)
"""MuJoCo's warnings of a diverged state; with each it resets the data (its auto-reset, on in every model here): the
position is finite again and the time restarts at 0."""


def diverged(data: mujoco.MjData) -> bool:
    """Whether MuJoCo met a diverged state in ``data`` (a non-finite position, or a warning of
    :data:`BAD_STATE_WARNINGS`: the data was reset since)."""
    return not np.isfinite(data.qpos).all() or any(data.warning[w].number for w in BAD_STATE_WARNINGS)


_PAIR_BITS_LIST: list[list[int]] = _PAIR_BITS.tolist()
_NO_CONTACT = ContactSummary(False, False, False, False, False)


@dataclass(frozen=True, eq=False)
class Scene:
    """A compiled validation scene and the ids a rollout needs (read-only; make one ``MjData`` per trial).

    Attributes:
        model: the compiled ``MjModel`` (world = UR5 ``base_link``).
        hand: the hand compiled alone (manifest, closure values, reference points in *its own* model).
        hand_ref: the hand name or manifest path the scene was built from.
        table_height: [m] z of the table top.
        arm_qpos: qpos addresses of the six arm joints (order of :data:`~softsig_service.arm.ur5.JOINT_NAMES`).
        arm_dof: dof addresses of the six arm joints.
        arm_actuators: actuator ids of the six arm servos.
        closure_actuators: scene actuator ids of the hand's closure actuators (same order as ``hand``'s).
        closure_open, closure_closed: open and closed control values of those actuators.
        posture_qpos: (scene qpos address, open value) to set before a posture closure starts.
        object_body: body id of the object; object_qpos: qpos address of its free joint (xyz then quat wxyz).
        object_geoms, hand_geoms, arm_geoms: geom ids of the object, the hand (``mount`` and below), the arm.
        obstacle_geoms: geom ids of the obstacles' free bodies (the hand may push them; the arm must not touch
            them).
        table_geom: geom id of the table.
        flange_body: body id of ``tool0``; mount_body: body id of the hand's ``mount`` (the same frame).
    """

    model: mujoco.MjModel
    hand: HandModel
    hand_ref: str
    table_height: float
    arm_qpos: IntArray
    arm_dof: IntArray
    arm_actuators: IntArray
    closure_actuators: IntArray
    closure_open: FloatArray
    closure_closed: FloatArray
    posture_qpos: tuple[tuple[int, float], ...]
    object_body: int
    object_qpos: int
    object_geoms: IntArray
    hand_geoms: IntArray
    arm_geoms: IntArray
    table_geom: int
    flange_body: int
    mount_body: int
    obstacle_geoms: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def timestep(self) -> float:
        """Simulation time step [s] (the hand manifest's ``simulation.timestep``)."""
        return float(self.model.opt.timestep)

    def make_data(self, q_arm: NDArray[np.float64], object_pose: NDArray[np.float64]) -> mujoco.MjData:
        """A fresh ``MjData``: arm at ``q_arm`` [rad] (servo targets there too), hand open, object at rest at
        ``object_pose`` (4x4 ``T_world_object``, its primitive frame as in ``TableObject.primitive_pose``)."""
        data = mujoco.MjData(self.model)
        data.qpos[self.arm_qpos] = q_arm
        data.ctrl[self.arm_actuators] = q_arm
        for adr, value in self.posture_qpos:
            data.qpos[adr] = value
        data.ctrl[self.closure_actuators] = self.closure_open
        self.set_object_pose(data, object_pose)
        mujoco.mj_forward(self.model, data)
        return data

    def set_object_pose(self, data: mujoco.MjData, T: NDArray[np.float64]) -> None:
        """Place the object's free body at ``T`` (4x4, world) with zero velocity (call ``mj_forward`` after)."""
        a = self.object_qpos
        data.qpos[a : a + 3] = T[:3, 3]
        data.qpos[a + 3 : a + 7] = matrix_to_quat(T[:3, :3])
        dof = int(self.model.jnt_dofadr[self.model.body_jntadr[self.object_body]])
        data.qvel[dof : dof + 6] = 0.0

    def object_position(self, data: mujoco.MjData) -> FloatArray:
        """World position [m] of the object's body frame (its centre)."""
        return np.array(data.xpos[self.object_body])

    def flange_pose(self, data: mujoco.MjData) -> FloatArray:
        """``T_world_tool0`` (4x4) in the simulation."""
        T = np.eye(4)
        T[:3, :3] = data.xmat[self.flange_body].reshape(3, 3)
        T[:3, 3] = data.xpos[self.flange_body]
        return T

    def contact_summary(self, data: mujoco.MjData) -> ContactSummary:
        """Which classes of geoms touch in the current contacts (distance <= 0: penetrating, carrying force)."""
        n = data.ncon
        if n == 0:
            return _NO_CONTACT
        con = data.contact
        cls, pair_bits = self._class_list, _PAIR_BITS_LIST  # plain lists: a dozen contacts a tick, read one by one
        bits = 0
        for (g1, g2), dist in zip(con.geom[:n].tolist(), con.dist[:n].tolist(), strict=True):
            if dist <= 0.0:
                bits |= pair_bits[cls[g1]][cls[g2]]
        if bits == 0:
            return _NO_CONTACT
        return ContactSummary(*(bool(bits & (1 << k)) for k in range(len(_PAIRS))))

    def object_touches_table(self, data: mujoco.MjData) -> bool:
        """Whether an object geom touches the table in the current contacts (distance <= 0)."""
        return self.contact_summary(data).object_table

    def vertical_extent(self, data: mujoco.MjData, geoms: IntArray) -> tuple[float, float]:
        """(lowest, highest) world z [m] of the geoms ``geoms``: of their axis-aligned bounding boxes (MuJoCo's
        ``geom_aabb``, in each geom's frame) as posed in ``data``; it contains every point of the geoms."""
        aabb = self.model.geom_aabb[geoms]
        rz = data.geom_xmat[geoms, 6:9]  # row z of each geom's rotation
        zc = data.geom_xpos[geoms, 2] + np.einsum("ij,ij->i", rz, aabb[:, :3])
        zh = np.einsum("ij,ij->i", np.abs(rz), aabb[:, 3:])
        return float(np.min(zc - zh)), float(np.max(zc + zh))

    def object_in_flange(self, data: mujoco.MjData) -> FloatArray:
        """Position [m] of the object's centre in the flange (``tool0`` = hand) frame."""
        R = data.xmat[self.flange_body].reshape(3, 3)
        return np.asarray(R.T @ (data.xpos[self.object_body] - data.xpos[self.flange_body]), dtype=np.float64)

    @functools.cached_property
    def object_reach(self) -> tuple[float, float]:
        """[m] the farthest point of the object's geoms (the corners of their bounding boxes, ``geom_aabb``) from
        the object body's origin and from its centre of mass."""
        m = self.model
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
        r_origin = r_com = 0.0
        com = np.asarray(m.body_ipos[self.object_body])
        for g in self.object_geoms:
            R = np.zeros(9)
            mujoco.mju_quat2Mat(R, m.geom_quat[g])
            corners = m.geom_aabb[g, :3] + signs * m.geom_aabb[g, 3:]
            in_body = m.geom_pos[g] + corners @ R.reshape(3, 3).T
            r_origin = max(r_origin, float(np.max(np.linalg.norm(in_body, axis=1))))
            r_com = max(r_com, float(np.max(np.linalg.norm(in_body - com, axis=1))))
        return r_origin, r_com

    @functools.cached_property
    def contact_margin(self) -> float:
        """[m] the largest ``geom_margin`` of the robot's and the object's geoms: MuJoCo makes a contact of a pair
        closer than the larger of its two margins (0 for the built-in hands and objects)."""
        geoms = np.concatenate([self.hand_geoms, self.arm_geoms, self.object_geoms])
        return float(np.max(self.model.geom_margin[geoms])) if geoms.size else 0.0

    @functools.cached_property
    def stray_colliders(self) -> bool:
        """Whether a geom that is neither the robot's, the object's, the table's nor an obstacle's can collide (a
        contact bit set): the approach replay and the ``clear_alone`` rule, which know only the robot's geoms,
        are off then."""
        m = self.model
        other = np.flatnonzero(self.geom_class == GEOM_OTHER)
        return bool(np.any((m.geom_contype[other] != 0) | (m.geom_conaffinity[other] != 0)))

    @functools.cached_property
    def _class_list(self) -> list[int]:
        """:attr:`geom_class` as a list (read per contact by :meth:`contact_summary`)."""
        return [int(c) for c in self.geom_class]

    @functools.cached_property
    def geom_class(self) -> NDArray[np.int8]:
        """Per geom: :data:`GEOM_OTHER`, :data:`GEOM_OBJECT`, :data:`GEOM_HAND`, :data:`GEOM_ARM`,
        :data:`GEOM_TABLE` or :data:`GEOM_OBSTACLE`."""
        cls = np.full(self.model.ngeom, GEOM_OTHER, dtype=np.int8)
        cls[self.obstacle_geoms] = GEOM_OBSTACLE
        cls[self.object_geoms] = GEOM_OBJECT
        cls[self.hand_geoms] = GEOM_HAND
        cls[self.arm_geoms] = GEOM_ARM
        cls[self.table_geom] = GEOM_TABLE
        return cls
