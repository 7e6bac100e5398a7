"""The hand library: manifests, xacro expansion, mimic couplings, mount poses, synergy closures, compiling hand
models for MuJoCo, closures, surfaces, summaries, archives and rendering."""

from softsig_service.hands.archive import is_archive, pack_folder, read_archive
from softsig_service.hands.assets import (
    ModelSource,
    check_relative_path,
    load_urdf_source,
    read_model_text,
)
from softsig_service.hands.closure import (
    closure_command,
    in_grasp_frame,
    prepare_data,
    reference_points_world,
    run_closure,
    simulate_closure,
    to_hand_frame,
)
from softsig_service.hands.collision_shapes import hand_collision_shapes
from softsig_service.hands.manifest import (
    ActuatorClosure,
    HandManifest,
    MountPose,
    PhysicalParameters,
    PostureClosure,
    ReferencePoint,
    SimulationSettings,
    SynergyClosure,
    load_manifest,
    manifest_from_dict,
)
from softsig_service.hands.mimic import Coupling, add_mimic_equalities, mimic_couplings, mimic_posture, strip_mimics
from softsig_service.hands.mjcf_source import confine_spec, load_mjcf_source
from softsig_service.hands.model import (
    HandModel,
    PointSpec,
    SpecSource,
    builtin_hand_names,
    builtin_hands_dir,
    compile_hand,
    hand_spec,
    load_hand,
    load_spec,
    resolve_hand_path,
)
from softsig_service.hands.mount_pose import apply_mount_pose, hand_frame_axes, mount_transform
from softsig_service.hands.render import draw_hand_frame, render_open_closed, save_png
from softsig_service.hands.summary import closure_summary, fingertip_spread, hand_info
from softsig_service.hands.surface import fibonacci_sphere, hand_surface_samples, sample_geom
from softsig_service.hands.synergy import add_synergy, synergy_controls, synergy_couplings, synergy_targets
from softsig_service.hands.trajectory import ClosureTrajectory, validate_trajectory
from softsig_service.hands.xacro_expand import ExpandedUrdf, cache_key, expand_xacro
from softsig_service.hands.xacro_sandbox import Forbidden, expand, main

__all__ = [
    "ActuatorClosure",
    "ClosureTrajectory",
    "Coupling",
    "ExpandedUrdf",
    "Forbidden",
    "HandManifest",
    "HandModel",
    "ModelSource",
    "MountPose",
    "PhysicalParameters",
    "PointSpec",
    "PostureClosure",
    "ReferencePoint",
    "SimulationSettings",
    "SpecSource",
    "SynergyClosure",
    "add_mimic_equalities",
    "add_synergy",
    "apply_mount_pose",
    "builtin_hand_names",
    "builtin_hands_dir",
    "cache_key",
    "check_relative_path",
    "closure_command",
    "closure_summary",
    "compile_hand",
    "confine_spec",
    "draw_hand_frame",
    "expand",
    "expand_xacro",
    "fibonacci_sphere",
    "fingertip_spread",
    "hand_collision_shapes",
    "hand_frame_axes",
    "hand_info",
    "hand_spec",
    "hand_surface_samples",
    "in_grasp_frame",
    "is_archive",
    "load_hand",
    "load_manifest",
    "load_mjcf_source",
    "load_spec",
    "load_urdf_source",
    "main",
    "manifest_from_dict",
    "mimic_couplings",
    "mimic_posture",
    "mount_transform",
    "pack_folder",
    "prepare_data",
    "read_archive",
    "read_model_text",
    "reference_points_world",
    "render_open_closed",
    "resolve_hand_path",
    "run_closure",
    "sample_geom",
    "save_png",
    "simulate_closure",
    "strip_mimics",
    "synergy_controls",
    "synergy_couplings",
    "synergy_targets",
    "to_hand_frame",
    "validate_trajectory",
]
