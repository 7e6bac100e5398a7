"""The campaign's speed-ups keep the verdicts: with the early stop (``RolloutConfig.early_stop``), the approach
replay (``RolloutConfig.replay_approach``) and the sparse constraint Jacobian every Table I cell gives the success and
the failure reason that the full schedule, simulated whole with MuJoCo's dense Jacobian, gives on the same seeds; the
stop rule fires on a known drop and never on a carry."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import mujoco
import pytest

from softsig_service.experiments.campaign_spec import TABLE1_CONDITIONS, TABLE1_OBJECTS, trial_seed
from softsig_service.experiments.trial import TrialResult, default_planner, run_trial
from softsig_service.objects import builtin_object
from softsig_service.simulation.diagnosis import summary
from softsig_service.simulation.rollout import STOP_RULES, RolloutConfig
from softsig_service.simulation.scene import build_scene

HAND = "pisa_iit_softhand"
FULL = RolloutConfig(early_stop=False, replay_approach=False)
SCHEDULE = 4.5
"""[s] the built-in SoftHand's full schedule: approach 1 s, closure 1 + 0.5 s, lift 1 s, hold 1 s."""


@contextmanager
def dense_jacobian(name: str) -> Iterator[None]:
    """The cached scene of ``name`` with MuJoCo's dense Jacobian for the duration (the physics before the change)."""
    scene = build_scene(HAND, builtin_object(name), default_planner().settings, ())
    saved = scene.model.opt.jacobian
    scene.model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    try:
        yield
    finally:
        scene.model.opt.jacobian = saved


def cell_trials() -> list[tuple[str, str, int, float, float]]:
    """(object, strategy, seed, sigma_r, sigma_t): one trial of every Table I cell, two of the noisy ones."""
    out = []
    for c, (sr, st) in enumerate(TABLE1_CONDITIONS):
        for o, name in enumerate(TABLE1_OBJECTS):
            for s, strategy in enumerate(("S", "C")):
                for k in range(2 if sr > 0 else 1):
                    out.append((name, strategy, trial_seed(11, (c, o, s), k), sr, st))
    return out


@pytest.fixture(scope="module")
def both() -> list[tuple[TrialResult, TrialResult]]:
    pairs = []
    for name, strategy, seed, sr, st in cell_trials():
        obj = builtin_object(name)
        with dense_jacobian(name):
            reference = run_trial(HAND, obj, strategy, seed=seed, sigma_r=sr, sigma_t=st, config=FULL)  # type: ignore[arg-type]
        fast = run_trial(HAND, obj, strategy, seed=seed, sigma_r=sr, sigma_t=st)  # type: ignore[arg-type]
        pairs.append((reference, fast))
    return pairs


def test_every_table1_cell_keeps_its_verdicts(both: list[tuple[TrialResult, TrialResult]]) -> None:
    verdicts = [(r.object, r.strategy, r.sigma_r, r.success, r.reason) for r, _ in both]
    assert verdicts == [(f.object, f.strategy, f.sigma_r, f.success, f.reason) for _, f in both]
    assert any(r.success for r, _ in both) and any(not r.success for r, _ in both)  # both kinds are covered
    for reference, fast in both:
        assert reference.sim_time == pytest.approx(SCHEDULE, abs=0.02)  # the reference ran its whole schedule
        if fast.success:
            assert fast.lift_height == pytest.approx(reference.lift_height, abs=0.005)


def test_decided_failures_stop_early_and_carries_run_to_the_end(both: list[tuple[TrialResult, TrialResult]]) -> None:
    stopped = [f for _, f in both if f.diagnosis.get("stopped")]
    assert stopped, "no trial stopped early"
    for _, fast in both:
        stop = fast.diagnosis.get("stopped")
        if fast.success:
            assert stop is None and fast.sim_time == pytest.approx(SCHEDULE, abs=0.02)
        elif stop is not None:
            assert stop["rule"] in STOP_RULES and fast.reason in ("dropped", "no_contact")
            assert fast.sim_time == pytest.approx(stop["time"], abs=1e-6) and fast.sim_time < SCHEDULE - 0.05
            assert fast.diagnosis["phases"][-1]["phase"] == "stopped"
            assert fast.diagnosis["phases"][-1]["hand_contacts"] == {}


def test_the_known_drop_stops_once_the_hand_has_risen_clear() -> None:
    """The SoftHand's S drops the nominal box early in the lift (docs/experiment_table1.md): the trial ends there,
    with the object on the table and the hand's lowest point above the box's top."""
    box = builtin_object("box")
    result = run_trial(HAND, box, "S", seed=0)
    assert not result.success and result.reason == "dropped"
    stop = result.diagnosis["stopped"]
    last = result.diagnosis["phases"][-1]
    assert stop["rule"] == "out_of_reach" and 2.5 < stop["time"] < 3.5  # during the lift (2.5 s to 3.5 s)
    assert last["touches_table"] and last["height"] == pytest.approx(box.height / 2, abs=0.003)
    assert "out of the hand's reach" in summary(result.diagnosis)
