"""The hand library: manifests, compiling hand models for MuJoCo, closures, surfaces, summaries and rendering."""

from softsig_service.hands.assets import (
    ModelSource,
    check_relative_path,
    load_urdf_source,
    read_model_text,
)
from softsig_service.hands.closure import (
    closure_command,
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
    PhysicalParameters,
    PostureClosure,
    ReferencePoint,
    SimulationSettings,
    load_manifest,
    manifest_from_dict,
)
from softsig_service.hands.model import (
    HandModel,
    PointSpec,
    builtin_hand_names,
    builtin_hands_dir,
    compile_hand,
    hand_spec,
    load_hand,
    resolve_hand_path,
)
from softsig_service.hands.render import render_open_closed, save_png
from softsig_service.hands.summary import closure_summary, fingertip_spread, hand_info
from softsig_service.hands.surface import fibonacci_sphere, hand_surface_samples, sample_geom
from softsig_service.hands.trajectory import ClosureTrajectory, validate_trajectory

__all__ = [
    "ActuatorClosure",
    "ClosureTrajectory",
    "HandManifest",
    "HandModel",
    "ModelSource",
    "PhysicalParameters",
    "PointSpec",
    "PostureClosure",
    "ReferencePoint",
    "SimulationSettings",
    "builtin_hand_names",
    "builtin_hands_dir",
    "check_relative_path",
    "closure_command",
    "closure_summary",
    "compile_hand",
    "fibonacci_sphere",
    "fingertip_spread",
    "hand_collision_shapes",
    "hand_info",
    "hand_spec",
    "hand_surface_samples",
    "load_hand",
    "load_manifest",
    "load_urdf_source",
    "manifest_from_dict",
    "prepare_data",
    "read_model_text",
    "reference_points_world",
    "render_open_closed",
    "resolve_hand_path",
    "run_closure",
    "sample_geom",
    "save_png",
    "simulate_closure",
    "to_hand_frame",
    "validate_trajectory",
]
