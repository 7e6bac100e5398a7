"""A hand's closure signature as ``softsig signature closure`` computes it, for the pictures that draw it."""

from __future__ import annotations

from softsig_service.hands.closure import in_grasp_frame, simulate_closure
from softsig_service.hands.model import HandModel
from softsig_service.signatures.closure import compute_closure_signature
from softsig_service.signatures.closure_types import ClosureSignature, Criterion, Method


def hand_closure_signature(
    hand: HandModel, method: Method = "ellipsoid", criterion: Criterion = "absolute"
) -> ClosureSignature:
    """The hand's closure signature as ``softsig signature closure`` computes it: a free-space closure (surface
    points for the mesh method), expressed in the grasp frame (``T_HG``; the hand frame when the manifest gives no
    ``grasp_frame``). Axis and anchor [m] are in the grasp frame."""
    traj = in_grasp_frame(hand, simulate_closure(hand, surface_points=None if method == "mesh" else 0))
    return compute_closure_signature(traj, method, criterion=criterion)
