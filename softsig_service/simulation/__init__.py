"""Everything that steps MuJoCo: the validation scene and rollout, the grasp of an object by a hand, its stiffness
matrices and the pull test."""

from softsig_service.simulation.grasp import grasp_object
from softsig_service.simulation.grasp_contacts import contact_forces, net_contact_wrench
from softsig_service.simulation.grasp_matrices import (
    ActuatorSynergies,
    GraspMatrices,
    actuator_synergies,
    grasp_matrices,
    grasp_stiffness_from_matrices,
    hand_object_contacts,
)
from softsig_service.simulation.grasp_scene import compile_with_object, placement_target, resolve_object
from softsig_service.simulation.grasp_state import Grasp, GraspSettings
from softsig_service.simulation.object_geom import set_object_shape
from softsig_service.simulation.pullout import PullSettings, check_directions, default_directions, pull_test, pull_tests
from softsig_service.simulation.rollout import (
    Perturbation,
    RolloutConfig,
    Run,
    SimOutcome,
    judge,
    simulate,
)
from softsig_service.simulation.scene import build_scene
from softsig_service.simulation.scene_model import ContactSummary, Scene
from softsig_service.simulation.stiffness_signature import (
    break_force_table,
    compute_stiffness_signature,
    find_power_grasp,
)

__all__ = [
    "ActuatorSynergies",
    "ContactSummary",
    "Grasp",
    "GraspMatrices",
    "GraspSettings",
    "Perturbation",
    "PullSettings",
    "RolloutConfig",
    "Run",
    "Scene",
    "SimOutcome",
    "actuator_synergies",
    "break_force_table",
    "build_scene",
    "check_directions",
    "compile_with_object",
    "compute_stiffness_signature",
    "contact_forces",
    "default_directions",
    "find_power_grasp",
    "grasp_matrices",
    "grasp_object",
    "grasp_stiffness_from_matrices",
    "hand_object_contacts",
    "judge",
    "net_contact_wrench",
    "placement_target",
    "pull_test",
    "pull_tests",
    "resolve_object",
    "set_object_shape",
    "simulate",
]
