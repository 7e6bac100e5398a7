"""Closure and stiffness signatures of a hand."""
