"""Top-grasp planning for the UR5: strategies S and C, the wrist-pose NLP (CasADi), clearances and the planner."""

from softsig_service.planning.clearance import Descent, HandClearance
from softsig_service.planning.planner import GraspPlan, HandPlanningModel, Planner, PlanRequest, planning_model
from softsig_service.planning.strategies import axis_angle_between_lines, strategy_s_poses
from softsig_service.planning.wrist_pose import WristPoseSolution, hand_rotation, solve_wrist_pose

__all__ = [
    "Descent",
    "GraspPlan",
    "HandClearance",
    "HandPlanningModel",
    "PlanRequest",
    "Planner",
    "WristPoseSolution",
    "axis_angle_between_lines",
    "hand_rotation",
    "planning_model",
    "solve_wrist_pose",
    "strategy_s_poses",
]
