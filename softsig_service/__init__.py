"""softsig: grasp planning for underactuated, compliant robot hands from closure and stiffness signatures."""

__version__ = "0.1.0"
