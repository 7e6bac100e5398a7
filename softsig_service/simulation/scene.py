"""The validation scene in MuJoCo: a table, the UR5 with a hand at ``tool0``, and an object as a free body.

Composed with :class:`mujoco.MjSpec` (docs/design.md §7) and compiled once per (hand, object shape, table height); a
trial changes only the poses, the controls and the ``MjData`` (:func:`build_scene` is cached per process).

Frames and units (docs/design.md §3): the world frame is the UR5 ``base_link`` (z up) at the origin; the table top is
the plane z = ``table_height`` [m] (default 0.0: the robot base stands on the table). Lengths [m], angles [rad],
masses [kg], stiffness [N·m/rad] or [N/m], damping [N·m·s/rad] or [N·s/m].

**UR5.** ``ur5_robot.urdf`` of example-robot-data, read at run time from the installed package (never copied):
the ``package://`` mesh references are rewritten in memory to the installed collision STL meshes (the visual
``.dae`` meshes cannot be loaded and are dropped), fixed links are kept (``fusestatic`` off) so that the
``tool0`` body exists. Inertias are the URDF's. Each joint has a position actuator with the gains of
:data:`ARM_KP` [N·m/rad] and :data:`ARM_KV` [N·m·s/rad], rotor inertia :data:`ARM_ARMATURE` [kg·m²], and every
arm body is gravity-compensated (``gravcomp = 1``, as the UR controller does); the hand's and the object's
weight are carried by the servos (sag below 1 mm at the flange for these gains).

**Hand.** Built exactly as :func:`softsig_service.hands.model.compile_hand` builds it (the same ``MjSpec`` with
the posture servos ``softsig_servo_*`` added for posture closures), then attached at ``tool0`` with
``MjSpec.attach`` through a frame with the identity pose, every name prefixed with :data:`HAND_PREFIX`: the
hand's ``mount`` body (the hand frame) coincides with ``tool0``. Its own contact bitmasks are kept.

**Contacts.** Bit 0 (value 1) is the environment bit the hands' models already collide with (their
``conaffinity`` has it): the table and the object have ``contype = 1``. Arm geoms have
``contype = ARM_BIT`` and ``conaffinity = 0``, and the table and object have ``ARM_BIT`` in their
``conaffinity``: the arm touches the table and the object (see ``arm_collision`` in
:mod:`softsig_service.simulation.rollout`) but neither itself nor the hand (its links overlap at the joints;
the hand is bolted to the flange). Static geoms (the base link on the table) never collide in MuJoCo. The table
is the plane z = ``table_height`` for contacts (drawn as a 1.8 m square).

**Simulation options.** Time step and integrator of the hand's manifest (``simulation.timestep``, 2 ms for the
built-in hands; ``implicitfast``), elliptic friction cones with ``impratio = 10`` (less creep of held objects
than MuJoCo's default pyramidal cones), gravity 9.81 m/s² along world -z. The constraint Jacobian is sparse
(``mjJAC_SPARSE``: the same equations as the dense default, about 10-25 % less time per step with the hand's
branching tree; ``tests/simulation/test_early_stop.py`` checks that every Table I cell keeps its verdicts).

**Object.** A free body from a :class:`~softsig_service.objects.TableObject`: its primitive (box,
cylinder, sphere, ellipsoid, or a mesh from its vertices and faces) with the object's ``mass`` [kg] (uniform
density) and sliding ``friction`` (torsional 0.005 m, rolling 0.0001 m, ``condim = 4``). MuJoCo combines the
friction of two geoms in contact by taking the larger: object-hand contacts use max(object, hand geom), and
object-table contacts max(object, :data:`TABLE_FRICTION`).
"""

from __future__ import annotations

import hashlib
import threading
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from softsig_service.arm.robots_dir import URDF_RELATIVE, find_robots_dir
from softsig_service.arm.ur5 import FLANGE_FRAME, JOINT_NAMES
from softsig_service.config import Settings, default_settings
from softsig_service.errors import InvalidHandModel
from softsig_service.geometry.quaternions import matrix_to_quat
from softsig_service.hands.manifest import load_manifest
from softsig_service.hands.model import HandModel, compile_hand, load_hand, resolve_hand_path
from softsig_service.objects import TableObject
from softsig_service.simulation.object_geom import set_object_shape
from softsig_service.simulation.scene_model import (
    ARM_ARMATURE,
    ARM_BIT,
    ARM_FORCE_LIMIT,
    ARM_KP,
    ARM_KV,
    ENV_BIT,
    HAND_PREFIX,
    OBJECT_BODY,
    OBJECT_ROLLING_FRICTION,
    OBJECT_TORSIONAL_FRICTION,
    TABLE_FRICTION,
    TABLE_GEOM,
    TABLE_HALF_SIZE,
    Scene,
)


def _ur5_spec(robots_dir: Path | None = None) -> mujoco.MjSpec:
    """The UR5 URDF as an ``MjSpec``: collision STL meshes from the installed package, no visuals, fixed
    links kept (``tool0`` is a body), gravity-compensated bodies and one position servo per joint."""
    robots = find_robots_dir(robots_dir)
    urdf_path = robots / URDF_RELATIVE
    root = ET.fromstring(urdf_path.read_text(encoding="utf-8"))
    for tag in ("gazebo", "transmission"):
        for el in root.findall(tag):
            root.remove(el)
    assets: dict[str, bytes] = {}
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
        for mesh in link.iter("mesh"):
            ref = mesh.get("filename", "")
            prefix = "package://example-robot-data/robots/"
            if not ref.startswith(prefix):
                raise InvalidHandModel("unexpected mesh reference in the UR5 URDF", field="urdf", value=ref)
            rel = ref[len(prefix) :]
            name = rel.replace("/", "_")
            assets[name] = (robots / rel).read_bytes()
            mesh.set("filename", name)
    mj = ET.SubElement(root, "mujoco")
    ET.SubElement(mj, "compiler", {"fusestatic": "false", "discardvisual": "false", "strippath": "false"})
    spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"), assets=assets)
    joints = {j.name: j for j in spec.joints}
    for k, name in enumerate(JOINT_NAMES):
        joint = joints[name]
        joint.armature = ARM_ARMATURE[k]
        act = spec.add_actuator(name=f"arm_{name}", target=name)
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_position(kp=ARM_KP[k], kv=ARM_KV[k])
        act.forcelimited = True
        act.forcerange = [-ARM_FORCE_LIMIT[k], ARM_FORCE_LIMIT[k]]
        act.ctrllimited = False
    for body in spec.bodies:
        if body.name != "world":
            body.gravcomp = 1.0
    for geom in spec.geoms:
        geom.contype = ARM_BIT
        geom.conaffinity = 0
        geom.rgba = [0.62, 0.66, 0.72, 1.0]
    return spec


def _hand_spec(hand_ref: str, settings: Settings) -> tuple[mujoco.MjSpec, HandModel]:
    """The hand's ``MjSpec`` exactly as :func:`compile_hand` builds it (posture servos included), and the
    hand compiled alone from it."""
    path = resolve_hand_path(hand_ref, settings)
    manifest = load_manifest(path, max_bytes=settings.limits.max_model_bytes)
    captured: list[mujoco.MjSpec] = []
    excluded = load_hand(hand_ref, settings).excluded  # the self-collision pairs found once per hand load
    hand = compile_hand(manifest, path.parent, settings.limits, edit=captured.append, excluded=excluded)
    return captured[0], hand


def _add_free_body(spec: mujoco.MjSpec, name: str, obj: TableObject, rgba: list[float], at_pose: bool) -> None:
    """``obj`` as the free body ``name`` (joint ``name_free``, geom ``name_geom``): environment contacts, its mass
    and friction; at its pose in the model when ``at_pose`` (an obstacle), else placed by ``make_data``."""
    body = spec.worldbody.add_body(name=name)
    if at_pose:
        T = obj.primitive_pose
        body.pos = T[:3, 3].tolist()
        body.quat = matrix_to_quat(T[:3, :3]).tolist()
    body.add_freejoint(name=f"{name}_free")
    geom = body.add_geom(name=f"{name}_geom")
    set_object_shape(spec, geom, obj.primitive(), f"{name}_mesh")
    geom.mass = obj.mass
    geom.friction = [obj.friction, OBJECT_TORSIONAL_FRICTION, OBJECT_ROLLING_FRICTION]
    geom.condim = 4
    geom.contype = ENV_BIT
    geom.conaffinity = ENV_BIT | ARM_BIT
    geom.rgba = rgba


def _add_table(spec: mujoco.MjSpec, table_height: float) -> None:
    """The table: the plane z = ``table_height`` [m], colliding with the environment and the arm."""
    table = spec.worldbody.add_geom(name=TABLE_GEOM)
    table.type = mujoco.mjtGeom.mjGEOM_PLANE
    table.size = [*TABLE_HALF_SIZE, 0.05]
    table.pos = [0.3, 0.0, table_height]
    table.friction = [TABLE_FRICTION, 0.005, 0.0001]
    table.contype = ENV_BIT
    table.conaffinity = ENV_BIT | ARM_BIT
    table.rgba = [0.78, 0.7, 0.58, 1.0]


def _compose(hand_ref: str, obj: TableObject, settings: Settings, obstacles: Sequence[TableObject] = ()) -> Scene:
    spec = _ur5_spec(settings.robots_dir)
    spec.modelname = "softsig_validation"
    spec.compiler.degree = False
    hand_spec, hand = _hand_spec(hand_ref, settings)
    sim = hand.manifest.simulation
    spec.option.timestep = sim.timestep
    spec.option.integrator = hand.model.opt.integrator
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    spec.option.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
    spec.visual.headlight.ambient = [0.4, 0.4, 0.4]
    spec.visual.headlight.diffuse = [0.6, 0.6, 0.6]

    flange = spec.body(FLANGE_FRAME)
    frame = flange.add_frame()
    spec.attach(hand_spec, prefix=HAND_PREFIX, frame=frame)

    th = obj.table_height
    _add_table(spec, th)
    light = spec.worldbody.add_light(name="key")
    light.pos = [0.6, -0.6, 1.5]
    light.dir = [-0.3, 0.3, -1.0]
    cam = spec.worldbody.add_camera(name="overview")
    cam.pos = [0.85, -0.42, 0.36]
    cam.mode = mujoco.mjtCamLight.mjCAMLIGHT_TARGETBODY
    cam.targetbody = OBJECT_BODY
    _add_free_body(spec, OBJECT_BODY, obj, [0.85, 0.35, 0.2, 1.0], at_pose=False)
    for k, obstacle in enumerate(obstacles):  # colliding as the object does, at their poses
        _add_free_body(spec, f"{OBSTACLE_BODY}{k}", obstacle, [0.35, 0.45, 0.7, 1.0], at_pose=True)
    try:
        model = spec.compile()
    except ValueError as exc:
        raise InvalidHandModel(f"MuJoCo cannot compile the validation scene: {exc}", field="hand") from None
    return _index(model, hand, hand_ref, th)


def _index(model: mujoco.MjModel, hand: HandModel, hand_ref: str, table_height: float) -> Scene:
    def body_id(name: str) -> int:
        return int(model.body(name).id)

    arm_joints = [model.joint(n) for n in JOINT_NAMES]
    mount = body_id(HAND_PREFIX + hand.model.body(hand.mount_body).name)
    # the hand's bodies: the mount and its descendants
    in_hand = np.zeros(model.nbody, dtype=bool)
    in_hand[mount] = True
    for b in range(mount + 1, model.nbody):
        in_hand[b] = in_hand[model.body_parentid[b]]
    obj = body_id(OBJECT_BODY)
    geom_body = model.geom_bodyid
    hand_geoms = np.flatnonzero(in_hand[geom_body])
    object_geoms = np.flatnonzero(geom_body == obj)
    obstacle_bodies = [b for b in range(model.nbody) if model.body(b).name.startswith(OBSTACLE_BODY)]
    obstacle_geoms = np.flatnonzero(np.isin(geom_body, obstacle_bodies))
    arm_bodies = {
        body_id(n)
        for n in (
            "base_link",
            "shoulder_link",
            "upper_arm_link",
            "forearm_link",
            "wrist_1_link",
            "wrist_2_link",
            "wrist_3_link",
            "ee_link",
        )
    }
    arm_geoms = np.array([g for g in range(model.ngeom) if int(geom_body[g]) in arm_bodies], dtype=np.int64)
    closure_ids = [int(model.actuator(HAND_PREFIX + hand.model.actuator(a).name).id) for a in hand.closure_actuators]
    posture: list[tuple[int, float]] = []
    for adr, value in hand.posture_qpos:
        j = int(np.flatnonzero(hand.model.jnt_qposadr == adr)[0])
        posture.append((int(model.joint(HAND_PREFIX + hand.model.joint(j).name).qposadr[0]), float(value)))
    return Scene(
        model=model,
        hand=hand,
        hand_ref=hand_ref,
        table_height=table_height,
        arm_qpos=np.array([int(j.qposadr[0]) for j in arm_joints], dtype=np.int64),
        arm_dof=np.array([int(j.dofadr[0]) for j in arm_joints], dtype=np.int64),
        arm_actuators=np.array([int(model.actuator(f"arm_{n}").id) for n in JOINT_NAMES], dtype=np.int64),
        closure_actuators=np.array(closure_ids, dtype=np.int64),
        closure_open=np.asarray(hand.closure_open, dtype=np.float64).copy(),
        closure_closed=np.asarray(hand.closure_closed, dtype=np.float64).copy(),
        posture_qpos=tuple(posture),
        object_body=obj,
        object_qpos=int(model.jnt_qposadr[model.body_jntadr[obj]]),
        object_geoms=object_geoms.astype(np.int64),
        hand_geoms=hand_geoms.astype(np.int64),
        arm_geoms=arm_geoms,
        table_geom=int(model.geom(TABLE_GEOM).id),
        flange_body=body_id(FLANGE_FRAME),
        mount_body=mount,
        obstacle_geoms=obstacle_geoms.astype(np.int64),
    )


def _shape_key(obj: TableObject) -> tuple[object, ...]:
    """What of an object goes into the compiled model: shape, size, mass, friction and table height."""
    mesh = b""
    if obj.vertices is not None and obj.faces is not None:
        mesh = np.ascontiguousarray(obj.vertices, dtype=np.float64).tobytes()
        mesh += np.ascontiguousarray(obj.faces, dtype=np.int64).tobytes()
    return (
        obj.kind,
        tuple(obj.dimensions),
        obj.standing,
        obj.mass,
        obj.friction,
        obj.table_height,
        hashlib.sha1(mesh).hexdigest(),
    )


def build_scene(
    hand_ref: str, obj: TableObject, settings: Settings | None = None, obstacles: Sequence[TableObject] = ()
) -> Scene:
    """The scene for ``hand_ref`` (built-in name or manifest path) and the shape of ``obj`` (its pose is not
    part of the model: place it with :meth:`Scene.make_data`), with ``obstacles`` as free bodies starting at their
    poses (those are part of the model). Compiled once per process and reused for every object of the same shape,
    mass, friction and table height among the same obstacles (thread-safe)."""
    settings = settings or default_settings()
    path = resolve_hand_path(hand_ref, settings)
    around = tuple((_shape_key(o), tuple(np.round(o.primitive_pose, 12).ravel().tolist())) for o in obstacles)
    key = (hand_ref, str(path), path.stat().st_mtime_ns, str(settings.hands_dir), str(settings.robots_dir),
           settings.limits, _shape_key(obj), around)  # fmt: skip
    with _CACHE_LOCK:
        scene = _CACHE.get(key)
        if scene is None:
            scene = _compose(hand_ref, obj, settings, obstacles)
            if len(_CACHE) >= _CACHE_SIZE:
                _CACHE.pop(next(iter(_CACHE)))
            _CACHE[key] = scene
    return scene


OBSTACLE_BODY = "obstacle_"
"""Name prefix of the obstacles' bodies (``obstacle_0``, ...)."""
_CACHE: dict[tuple[object, ...], Scene] = {}
_CACHE_SIZE = 32
_CACHE_LOCK = threading.Lock()


def build_object_alone(obj: TableObject, scene: Scene) -> mujoco.MjModel:
    """The object of ``scene`` alone on its table: the same table, the same free body (shape, mass, friction) and
    the same simulation options as ``scene.model``, nothing else; its free joint is qpos 0-6 and dofs 0-5. An object
    the hand does not touch moves in it as in the scene (MuJoCo solves the object's constraint island apart from the
    robot's; the two agree to about 1e-11 m over a second, the order of floating-point rounding:
    ``tests/simulation/test_approach_replay.py``). Compiled once per shape and options (thread-safe)."""
    opt = scene.model.opt
    options = (float(opt.timestep), int(opt.integrator), int(opt.cone), float(opt.impratio), int(opt.jacobian),
               tuple(float(g) for g in opt.gravity))  # fmt: skip
    key = ("object_alone", _shape_key(obj), options)
    with _CACHE_LOCK:
        model = _ALONE.get(key)
        if model is None:
            spec = mujoco.MjSpec()
            spec.modelname = "softsig_object_alone"
            spec.compiler.degree = False
            spec.option.timestep, spec.option.integrator, spec.option.cone = options[0], options[1], options[2]
            spec.option.impratio, spec.option.jacobian = options[3], options[4]
            spec.option.gravity = list(options[5])
            _add_table(spec, obj.table_height)
            _add_free_body(spec, OBJECT_BODY, obj, [0.85, 0.35, 0.2, 1.0], at_pose=False)
            model = spec.compile()
            if len(_ALONE) >= _CACHE_SIZE:
                _ALONE.pop(next(iter(_ALONE)))
            _ALONE[key] = model
    return model


_ALONE: dict[tuple[object, ...], mujoco.MjModel] = {}
