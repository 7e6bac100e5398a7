"""Every built-in hand other than the SoftHand carries each nominal object of docs/design.md §7 with strategy S at
sigma = 0 (the judge of :mod:`softsig_service.simulation.rollout`), or the exception is documented and shown.

The bands on sag and slip are the figures the hands' READMEs report (hands/<hand>/README.md, "Top grasps in the
validation rollout"); sag and slip never fail a carried object, these bands keep the READMEs true."""

from __future__ import annotations

import pytest

from softsig_service.experiments.trial import default_planner, run_trial
from softsig_service.objects import builtin_object
from softsig_service.planning.planner import PlanRequest

HALF_LIFT = 0.5 * 0.15
SAG_BAND: dict[str, tuple[float, float]] = {
    "parallel_gripper": (-0.001, 0.005),  # rigid: the object moves with the flange
    "sdm_hand": (0.02, 0.05),  # caught by the fingers 3 cm into the lift (fingertips locked on the table)
    "rbo_hand2": (-0.001, 0.05),  # soft fingers: up to a few centimetres
}
CARRIED = [
    (hand, obj)
    for hand in ("rbo_hand2", "sdm_hand", "parallel_gripper")
    for obj in ("box", "apple", "cylinder")
    if (hand, obj) != ("parallel_gripper", "apple")
]


@pytest.mark.parametrize(("hand", "obj"), CARRIED)
def test_hand_carries_the_nominal_object_with_strategy_s(hand: str, obj: str) -> None:
    r = run_trial(hand, builtin_object(obj), "S", seed=0)
    assert r.success, r.to_json_dict()
    assert r.touching_end and not r.touching_table_end and r.lift_height >= HALF_LIFT
    assert r.sag is not None and r.slip is not None
    lo, hi = SAG_BAND[hand]
    assert lo < r.sag < hi
    assert 0.0 <= r.slip < 0.005


def test_parallel_gripper_apple_is_held_only_when_the_pads_reach_its_equator() -> None:
    """hands/parallel_gripper/README.md: with the planner's 5 mm descent margin (more than the 2.5 mm of
    clearance per jaw around the 80 mm apple) the pads stop on the apple's cap and squeeze it out; the same
    grasp taken 12 mm below the equator (2 mm margin) carries it."""
    apple = builtin_object("apple")
    equator = float(apple.center[2])
    planner = default_planner()
    tip_depth = 0.15  # [m] flange to jaw tips

    default = planner.plan(PlanRequest(hand="parallel_gripper", obj=apple, strategy="S"))
    assert default.success and default.grasp_pose is not None
    assert default.grasp_pose[2, 3] - tip_depth > equator + 0.010  # pad tips more than 1 cm above the equator
    r = run_trial("parallel_gripper", apple, "S", seed=0, plan=default)
    assert not r.success and r.reason == "dropped" and r.touching_after_close

    deep = planner.plan(PlanRequest(hand="parallel_gripper", obj=apple, strategy="S", margin=0.002))
    assert deep.success and deep.grasp_pose is not None
    assert deep.grasp_pose[2, 3] - tip_depth < equator - 0.005  # pad tips below the equator
    r = run_trial("parallel_gripper", apple, "S", seed=0, plan=deep)
    assert r.success, r.to_json_dict()
    assert r.sag is not None and r.sag < 0.005
