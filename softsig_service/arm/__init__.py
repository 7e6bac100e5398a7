"""The UR5 arm: Pinocchio kinematics with closed-form and numeric IK, and coal collision checks of arm, hand, table
and object."""

from softsig_service.arm.arm_geometry import ArmGeometry, arm_geometry, link_name
from softsig_service.arm.collision import CollisionWorld
from softsig_service.arm.collision_report import CollisionReport, check_finite, check_margin, make_report, min_optional
from softsig_service.arm.numeric_ik import levenberg_marquardt
from softsig_service.arm.robots_dir import SRDF_RELATIVE, URDF_RELATIVE, find_robots_dir
from softsig_service.arm.shapes import (
    HandShape,
    ObjectShape,
    ShapeSpec,
    check_shape_size,
    coal_primitive,
    convex_hull,
    local_aabb,
    object_geometry,
)
from softsig_service.arm.ur5 import UR5, IKResult, load_ur5
from softsig_service.arm.ur_ik import URParameters, ur_parameters

__all__ = [
    "SRDF_RELATIVE",
    "UR5",
    "URDF_RELATIVE",
    "ArmGeometry",
    "CollisionReport",
    "CollisionWorld",
    "HandShape",
    "IKResult",
    "ObjectShape",
    "ShapeSpec",
    "URParameters",
    "arm_geometry",
    "check_finite",
    "check_margin",
    "check_shape_size",
    "coal_primitive",
    "convex_hull",
    "find_robots_dir",
    "levenberg_marquardt",
    "link_name",
    "load_ur5",
    "local_aabb",
    "make_report",
    "min_optional",
    "object_geometry",
    "ur_parameters",
]
