"""Why a trial ended as it did: a known drop (the SoftHand's S on the nominal box, docs/experiment_table1.md) and a
known carry (its C) give the diagnosis one expects at each phase boundary, and the one-line summary says so."""

from __future__ import annotations

import pytest

from softsig_service.experiments.trial import run_trial
from softsig_service.objects import builtin_object
from softsig_service.simulation.diagnosis import PHASES, summary
from softsig_service.simulation.rollout import RolloutConfig

BOX = builtin_object("box")


@pytest.fixture(scope="module")
def drop_and_carry() -> tuple[object, object]:
    full = RolloutConfig(early_stop=False)  # every phase boundary (the drop would stop early in the lift)
    return (
        run_trial("pisa_iit_softhand", BOX, "S", seed=0, config=full),
        run_trial("pisa_iit_softhand", BOX, "C", seed=0, config=full),
    )


def test_a_drop_is_seen_leaving_the_hand_during_the_lift(drop_and_carry: tuple[object, object]) -> None:
    drop = drop_and_carry[0]
    assert not drop.success and drop.reason == "dropped"  # type: ignore[attr-defined]
    d = drop.diagnosis  # type: ignore[attr-defined]
    by_phase = {s["phase"]: s for s in d["phases"]}
    assert tuple(by_phase) == PHASES
    assert by_phase["closure"]["hand_contacts"] and by_phase["closure"]["touches_table"]
    for phase in ("lift", "hold"):
        assert by_phase[phase]["hand_contacts"] == {} and by_phase[phase]["touches_table"]
        assert by_phase[phase]["height"] == pytest.approx(BOX.height / 2, abs=0.003)  # back on the table
    assert by_phase["closure"]["time"] < d["released_at"] <= by_phase["lift"]["time"]
    assert "left the hand" in summary(d) and "on the table, not in the hand" in summary(d)


def test_a_carry_is_held_off_the_table_to_the_end(drop_and_carry: tuple[object, object]) -> None:
    carry = drop_and_carry[1]
    assert carry.success  # type: ignore[attr-defined]
    d = carry.diagnosis  # type: ignore[attr-defined]
    hold = d["phases"][-1]
    assert hold["phase"] == "hold" and not hold["touches_table"] and len(hold["hand_contacts"]) >= 2
    assert sum(hold["hand_contacts"].values()) > BOX.mass * 9.81  # the hand's grip carries more than the weight
    assert hold["height"] > 0.1 and d["released_at"] is None
    closure = d["phases"][1]
    assert hold["offset"] == pytest.approx(closure["offset"], abs=0.02)  # it moved with the hand
    assert "left the hand" not in summary(d) and "held by" in summary(d)


def test_a_trial_that_never_simulated_has_no_diagnosis() -> None:
    far = builtin_object("box", x=1.4)
    result = run_trial("pisa_iit_softhand", far, "C", seed=0)
    assert not result.success and result.diagnosis == {} and summary({}) == "nothing simulated"
