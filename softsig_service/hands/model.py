"""Load a hand (built-in name or a user's ``hand.toml``) into a compiled MuJoCo model with resolved frames.

The compiled model holds the hand alone with its ``mount`` body welded to the world, so the hand frame is the
world frame of this model at rest (the mount body's frame, moved by the manifest's ``mount_pose`` when it has one;
docs/design.md §3). A ``.xacro`` model is expanded first (:mod:`softsig_service.hands.xacro_expand`); a URDF's
``<mimic>`` tags become joint equalities (:mod:`softsig_service.hands.mimic`). For a posture closure (fully actuated
hands, URDF hands) a position servo is added to each joint the posture names; a synergy closure adds its
realisation (:mod:`softsig_service.hands.synergy`). Models are cached per manifest
file and modification time: a request passes numbers, not files.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import mujoco
import numpy as np
from numpy.typing import NDArray

from softsig_service.config import ModelLimits, Settings, default_settings
from softsig_service.errors import FrameNotFound, HandNotFound, InvalidHandModel, ModelTooLarge, UnsafePath
from softsig_service.hands.assets import load_urdf_source
from softsig_service.hands.calibration import apply_calibration
from softsig_service.hands.manifest import (
    HandManifest,
    PostureClosure,
    ReferencePoint,
    SynergyClosure,
    load_manifest,
)
from softsig_service.hands.mimic import (
    Coupling,
    add_mimic_equalities,
    mimic_couplings,
    mimic_posture,
    strip_mimics,
)
from softsig_service.hands.mjcf_source import confine_spec, load_mjcf_source
from softsig_service.hands.mount_pose import apply_mount_pose, mount_transform
from softsig_service.hands.posture_checks import check_posture
from softsig_service.hands.self_collision import ExcludedPair, add_excludes, excluded_pairs
from softsig_service.hands.synergy import add_synergy, synergy_controls, synergy_couplings
from softsig_service.hands.xacro_expand import ExpandedUrdf, expand_xacro

_INTEGRATORS = {
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}
SERVO_PREFIX = "softsig_servo_"


@dataclass(frozen=True)
class PointSpec:
    """How to read a reference point: a site, or a body plus an offset [m] in that body's frame."""

    name: str
    kind: Literal["site", "body"]
    id: int
    offset: tuple[float, float, float]


@dataclass(frozen=True)
class HandModel:
    """A compiled hand: manifest, folder, MuJoCo model, mount body, reference points and closure controls."""

    manifest: HandManifest
    folder: Path
    model: mujoco.MjModel
    mount_body: int
    points: tuple[PointSpec, ...]
    closure_actuators: tuple[int, ...]
    """Actuator ids ramped by the closure (the manifest's actuators, or the added posture servos)."""
    closure_open: NDArray[np.float64]
    closure_closed: NDArray[np.float64]
    """Open and closed control values for ``closure_actuators``."""
    posture_qpos: tuple[tuple[int, float], ...]
    """For posture and synergy closures: (qpos address, open value) set before the closure starts."""
    hand_frame: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    """``T_MH`` (4x4): the hand frame in the description's mount-body frame (``mount_pose``; [m])."""
    grasp_frame: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    """``T_HG`` (4x4): the grasp frame in the hand (= flange) frame (``grasp_frame``; [m])."""
    mimics: tuple[Coupling, ...] = ()
    """The URDF's mimic couplings, resolved to their root joints."""
    synergy: tuple[Coupling, ...] = ()
    """For a synergy closure: the joints s drives (``q = multiplier * s + offset``)."""
    expanded: ExpandedUrdf | None = None
    """For a xacro model: the expanded URDF (its SHA-256 is stored with the hand)."""
    excluded: tuple[ExcludedPair, ...] = ()
    """Body pairs whose contacts are not checked, with the reason for each
    (:mod:`softsig_service.hands.self_collision`)."""
    knuckle: PointSpec | None = None
    """The manifest's ``knuckle`` point (placement ``"knuckle"``), or None."""

    @property
    def name(self) -> str:
        """The hand's name from its manifest."""
        return self.manifest.name

    @property
    def point_names(self) -> tuple[str, ...]:
        """Reference point names in tracking order."""
        return tuple(p.name for p in self.points)


def builtin_hands_dir(settings: Settings | None = None) -> Path:
    """The folder of the built-in hands."""
    return (settings or default_settings()).hands_dir


def builtin_hand_names(settings: Settings | None = None) -> list[str]:
    """Names of the built-in hands: the sub-folders of ``hands/`` holding a ``hand.toml``."""
    root = builtin_hands_dir(settings)
    return sorted(p.parent.name for p in root.glob("*/hand.toml"))


def resolve_hand_path(ref: str, settings: Settings | None = None) -> Path:
    """Map a built-in hand name or a path to ``hand.toml`` (or its folder) onto the manifest path."""
    candidate = Path(ref)
    if candidate.suffix == ".toml":
        if not candidate.is_file():
            raise HandNotFound("manifest file not found", field="hand", value=candidate.name)
        return candidate.resolve()
    if candidate.is_dir() and (candidate / "hand.toml").is_file():
        return (candidate / "hand.toml").resolve()
    path = builtin_hands_dir(settings) / ref / "hand.toml"
    if "/" not in ref and path.is_file():
        return path.resolve()
    raise HandNotFound(
        "unknown hand: give a built-in name or a path to hand.toml",
        field="hand",
        value=ref,
        choices=builtin_hand_names(settings),
    )


def load_hand(ref: str, settings: Settings | None = None) -> HandModel:
    """Load (or fetch from the cache) the hand named ``ref`` or described by the manifest at ``ref``."""
    settings = settings or default_settings()
    path = resolve_hand_path(ref, settings)
    return _load_cached(str(path), path.stat().st_mtime_ns, settings.limits)


@functools.lru_cache(maxsize=32)
def _load_cached(path: str, _mtime_ns: int, limits: ModelLimits) -> HandModel:
    manifest_path = Path(path)
    manifest = load_manifest(manifest_path, max_bytes=limits.max_model_bytes)
    return compile_hand(manifest, manifest_path.parent, limits)


@dataclass(frozen=True)
class SpecSource:
    """A fresh ``MjSpec`` of a hand's model file, and for URDF/xacro the URDF text (mimic tags) and expansion."""

    spec: mujoco.MjSpec
    urdf_xml: str | None = None
    expanded: ExpandedUrdf | None = None


def load_spec(manifest: HandManifest, folder: Path, limits: ModelLimits) -> SpecSource:
    """The hand's model file as an ``MjSpec`` (checked paths and sizes), without softsig's additions."""
    model_path = (folder / manifest.model).resolve()
    if Path(manifest.model).is_absolute() or not model_path.is_relative_to(folder.resolve()):
        raise UnsafePath("the model file must lie inside the hand's folder", field="model", value=manifest.model)
    if manifest.model_format in ("urdf", "xacro"):
        expanded = None
        if manifest.model_format == "xacro":
            if not model_path.is_file():
                raise InvalidHandModel("model file not found in the hand's folder", field="model", value=manifest.model)
            expanded = expand_xacro(model_path, folder, manifest.xacro_mappings(), limits)
        src = load_urdf_source(model_path, limits, hand_root=folder, text=expanded.xml if expanded else None)
        return SpecSource(_parse_spec(strip_mimics(src.xml), src.assets, "URDF"), src.xml, expanded)
    src = load_mjcf_source(model_path, limits)
    return SpecSource(_parse_spec(src.xml, src.assets, "MJCF"))


def _parse_spec(xml: str, assets: dict[str, bytes], kind: str) -> mujoco.MjSpec:
    """Parse ``xml`` with only ``assets`` to read from, every file of the spec confined to them."""
    try:
        spec = mujoco.MjSpec.from_string(xml, assets=assets)
    except ValueError as exc:
        raise InvalidHandModel(f"MuJoCo cannot parse the {kind}: {exc}", field="model") from None
    confine_spec(spec, assets)
    return spec


def hand_spec(manifest: HandManifest, folder: Path, limits: ModelLimits) -> mujoco.MjSpec:
    """A fresh ``MjSpec`` of the hand's model file (checked paths and sizes), without softsig's additions."""
    return load_spec(manifest, folder, limits).spec


def compile_hand(
    manifest: HandManifest,
    folder: Path,
    limits: ModelLimits,
    edit: Callable[[mujoco.MjSpec], None] | None = None,
    excluded: tuple[ExcludedPair, ...] | None = None,
) -> HandModel:
    """Build the hand's ``MjSpec``, add posture servos, compile, check limits and resolve every name.

    ``edit`` may add to the spec before compiling (an obstacle, an object); the result is not cached.
    ``excluded`` are the self-collision pairs not to check; without them they are found on the hand compiled
    alone (:func:`~softsig_service.hands.self_collision.excluded_pairs`), which costs one more compile when
    there are any or when ``edit`` is given (pass ``hand.excluded`` of a loaded hand to skip that).
    """
    if excluded is not None:
        return _build_hand(manifest, folder, limits, edit, excluded)
    plain = _build_hand(manifest, folder, limits, None, ())
    src = load_spec(manifest, folder, limits)
    found = excluded_pairs(plain.model, plain.posture_qpos, src.urdf_xml, folder, limits)
    if not found and edit is None:
        return plain
    return _build_hand(manifest, folder, limits, edit, found, src)


def _build_hand(
    manifest: HandManifest,
    folder: Path,
    limits: ModelLimits,
    edit: Callable[[mujoco.MjSpec], None] | None,
    excluded: tuple[ExcludedPair, ...],
    src: SpecSource | None = None,
) -> HandModel:
    src = src or load_spec(manifest, folder, limits)
    spec = src.spec
    apply_calibration(spec, manifest.calibration)
    T_MH = mount_transform(manifest.mount_pose)
    apply_mount_pose(spec, manifest.mount, T_MH)
    closure = manifest.closure
    mimics = mimic_couplings(src.urdf_xml) if src.urdf_xml is not None else {}
    coupled = synergy_couplings(closure, mimics) if isinstance(closure, SynergyClosure) else []
    add_mimic_equalities(spec, mimics, skip={c.joint for c in coupled}, timestep=manifest.simulation.timestep)
    add_excludes(spec, excluded)
    if edit is not None:
        edit(spec)
    sim = manifest.simulation
    spec.option.timestep = sim.timestep
    spec.option.integrator = _INTEGRATORS[sim.integrator]
    if isinstance(closure, SynergyClosure):
        add_synergy(spec, closure, coupled)
    if isinstance(closure, PostureClosure):
        joint_names = {j.name for j in spec.joints}
        for k, joint in enumerate(closure.open):
            if joint not in joint_names:
                raise FrameNotFound(
                    "posture names a joint the model does not have",
                    field=f"closure.open.{joint}",
                    value=joint,
                    choices=joint_names,
                )
            act = spec.add_actuator(name=f"{SERVO_PREFIX}{k}_{joint}", target=joint)
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            act.set_to_position(kp=closure.kp, kv=closure.kv)
            if closure.force_limit is not None:
                act.forcelimited = True
                act.forcerange = [-closure.force_limit, closure.force_limit]
    try:
        model = spec.compile()
    except ValueError as exc:
        raise InvalidHandModel(f"MuJoCo cannot compile the model: {exc}", field="model") from None
    _check_size(model, limits)
    mount = _lookup(model, "body", manifest.mount, "mount")
    if model.body_jntnum[mount] != 0 or model.body_parentid[mount] != 0:
        raise InvalidHandModel(
            "the mount body must be a child of the world with no joint (the wrist is fixed)",
            field="mount",
            value=manifest.mount,
        )
    points = _resolve_points(manifest, model, mount, T_MH)
    knuckle = None if manifest.knuckle is None else _resolve_point(manifest.knuckle, model, mount, T_MH, "knuckle")
    if isinstance(closure, SynergyClosure):
        actuators, open_ctrl, closed_ctrl, posture = synergy_controls(closure, coupled, model)
    else:
        if isinstance(closure, PostureClosure):
            check_posture(model, closure)
        actuators, open_ctrl, closed_ctrl, posture = _closure_controls(manifest, model)
    posture = mimic_posture(model, mimics, posture)
    return HandModel(
        manifest=manifest,
        folder=folder,
        model=model,
        mount_body=mount,
        points=points,
        closure_actuators=actuators,
        closure_open=open_ctrl,
        closure_closed=closed_ctrl,
        posture_qpos=posture,
        hand_frame=T_MH,
        grasp_frame=mount_transform(manifest.grasp_frame),
        mimics=tuple(mimics.values()),
        synergy=tuple(coupled),
        knuckle=knuckle,
        expanded=src.expanded,
        excluded=excluded,
    )


def _names(model: mujoco.MjModel, kind: Literal["body", "site", "actuator", "joint"]) -> list[str]:
    count = {"body": model.nbody, "site": model.nsite, "actuator": model.nu, "joint": model.njnt}[kind]
    getter = {"body": model.body, "site": model.site, "actuator": model.actuator, "joint": model.joint}[kind]
    return [getter(i).name for i in range(count) if getter(i).name]


_OBJ_TYPES = {
    "body": mujoco.mjtObj.mjOBJ_BODY,
    "site": mujoco.mjtObj.mjOBJ_SITE,
    "actuator": mujoco.mjtObj.mjOBJ_ACTUATOR,
    "joint": mujoco.mjtObj.mjOBJ_JOINT,
}


def _lookup(model: mujoco.MjModel, kind: Literal["body", "site", "actuator", "joint"], name: str, field: str) -> int:
    """The id of the named element, or :class:`FrameNotFound` naming ``field`` and the model's names."""
    idx = int(mujoco.mj_name2id(model, _OBJ_TYPES[kind], name))
    if idx < 0:
        raise FrameNotFound(f"{kind} not found", field=field, value=name, choices=_names(model, kind))
    return idx


def _check_size(model: mujoco.MjModel, limits: ModelLimits) -> None:
    for what, value, limit in (
        ("bodies", model.nbody, limits.max_bodies),
        ("degrees of freedom", model.nv, limits.max_dofs),
        ("mesh vertices", model.nmeshvert, limits.max_mesh_vertices),
    ):
        if value > limit:
            raise ModelTooLarge(f"model has more {what} than the limit of {limit}", field="model", value=value)


def _resolve_points(
    manifest: HandManifest, model: mujoco.MjModel, mount: int, T_MH: NDArray[np.float64]
) -> tuple[PointSpec, ...]:
    """The reference points; a ``body`` point on the mount body keeps its offset in the description's frame."""
    if manifest.reference_points is None:
        sites = [n for n in _names(model, "site") if n.endswith("_tip")]
        specs = [PointSpec(n, "site", model.site(n).id, (0.0, 0.0, 0.0)) for n in sites]
        wrist = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "wrist")
        if wrist >= 0:
            specs.append(PointSpec("wrist", "site", wrist, (0.0, 0.0, 0.0)))
        else:
            mount = model.body(manifest.mount).id
            specs.append(PointSpec("wrist", "body", mount, (0.0, 0.0, 0.0)))
        if len(specs) < 4:
            raise InvalidHandModel(
                "no reference_points given and fewer than 4 default points (sites named *_tip + wrist) found",
                field="reference_points",
                value=[s.name for s in specs],
            )
        return tuple(specs)
    return tuple(
        _resolve_point(p, model, mount, T_MH, f"reference_points[{k}]") for k, p in enumerate(manifest.reference_points)
    )


def _resolve_point(
    p: ReferencePoint, model: mujoco.MjModel, mount: int, T_MH: NDArray[np.float64], field: str
) -> PointSpec:
    """One manifest point (``field`` names it in errors); a ``body`` point on the mount body keeps its offset in
    the description's frame."""
    if p.site is not None:
        return PointSpec(p.name, "site", _lookup(model, "site", p.site, f"{field}.site"), (0.0, 0.0, 0.0))
    assert p.body is not None
    bid = _lookup(model, "body", p.body, f"{field}.body")
    offset = p.offset
    if bid == mount:  # the mount body's frame is now the hand frame: p_H = R_MH^T (p_M - o_MH)
        local = T_MH[:3, :3].T @ (np.asarray(p.offset) - T_MH[:3, 3])
        offset = (float(local[0]), float(local[1]), float(local[2]))
    return PointSpec(p.name, "body", bid, offset)


def _closure_controls(
    manifest: HandManifest, model: mujoco.MjModel
) -> tuple[tuple[int, ...], NDArray[np.float64], NDArray[np.float64], tuple[tuple[int, float], ...]]:
    closure = manifest.closure
    assert not isinstance(closure, SynergyClosure)
    if isinstance(closure, PostureClosure):
        ids, lo, hi, posture = [], [], [], []
        for k, joint in enumerate(closure.open):
            ids.append(model.actuator(f"{SERVO_PREFIX}{k}_{joint}").id)
            lo.append(closure.open[joint])
            hi.append(closure.closed[joint])
            posture.append((int(model.jnt_qposadr[model.joint(joint).id]), closure.open[joint]))
        return tuple(ids), np.array(lo), np.array(hi), tuple(posture)
    ids = [_lookup(model, "actuator", name, f"closure.actuators[{k}]") for k, name in enumerate(closure.actuators)]
    n = len(ids)
    return tuple(ids), np.full(n, closure.open), np.full(n, closure.closed), ()
