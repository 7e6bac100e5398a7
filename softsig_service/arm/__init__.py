"""The UR5 arm: Pinocchio kinematics with closed-form and numeric IK, and coal collision checks of arm, hand, table and
object.
"""

from softsig_service.arm.collision import (
    CollisionReport,
    CollisionWorld,
    HandShape,
    ObjectShape,
    ShapeSpec,
    convex_hull,
    object_geometry,
)
from softsig_service.arm.ur5 import UR5, IKResult, URParameters, find_robots_dir, load_ur5

__all__ = [
    "UR5",
    "CollisionReport",
    "CollisionWorld",
    "HandShape",
    "IKResult",
    "ObjectShape",
    "ShapeSpec",
    "URParameters",
    "convex_hull",
    "find_robots_dir",
    "load_ur5",
    "object_geometry",
]
