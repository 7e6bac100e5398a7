"""Top-grasp planning for the UR5: strategies S and C, the wrist-pose NLP (CasADi), clearances and the planner."""

from softsig_service.planning.clearance import Descent, HandClearance, HandGeometry
from softsig_service.planning.hand_model import (
    DEFAULT_PLACEMENT,
    PLACEMENTS,
    HandPlanningModel,
    Placement,
    build_planning_model,
    cached_planning_model,
    planning_model,
    remember_planning_model,
)
from softsig_service.planning.planner import Planner
from softsig_service.planning.request import GraspPlan, PlanRequest
from softsig_service.planning.strategies import axis_angle_between_lines, relative_poses, strategy_s_poses
from softsig_service.planning.strategy_r import RChoice, c_relative_theta, solve_strategy_r
from softsig_service.planning.wrist_pose import (
    WristPoseSolution,
    hand_rotation,
    solve_wrist_pose,
    solve_wrist_pose_unchecked,
)

__all__ = [
    "DEFAULT_PLACEMENT",
    "PLACEMENTS",
    "Descent",
    "GraspPlan",
    "HandClearance",
    "HandGeometry",
    "HandPlanningModel",
    "Placement",
    "PlanRequest",
    "Planner",
    "RChoice",
    "WristPoseSolution",
    "axis_angle_between_lines",
    "build_planning_model",
    "c_relative_theta",
    "cached_planning_model",
    "hand_rotation",
    "planning_model",
    "relative_poses",
    "remember_planning_model",
    "solve_strategy_r",
    "solve_wrist_pose",
    "solve_wrist_pose_unchecked",
    "strategy_s_poses",
]
