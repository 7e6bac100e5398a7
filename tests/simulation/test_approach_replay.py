"""Approach replay (softsig_service/simulation/approach_replay.py): a trial resumed from its plan's shared recording is
where the full simulation would be at that tick (the robot bit for bit, the object to rounding), it resumes before
anything of the robot comes near the object, and it gives the verdicts the full simulation gives."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import pytest

from softsig_service.experiments.campaign_spec import TABLE1_CONDITIONS, trial_seed
from softsig_service.experiments.trial import run_trial
from softsig_service.objects import builtin_object
from softsig_service.simulation import approach_replay, rollout
from softsig_service.simulation.rollout import RolloutConfig
from softsig_service.simulation.scene import build_scene

HAND = "pisa_iit_softhand"
FULL = RolloutConfig(replay_approach=False)


def _resumes(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """Every ``Run.resume`` call's prefix and replay, collected."""
    seen: list[dict[str, Any]] = []
    original = rollout.Run.resume

    def spy(self: rollout.Run, prefix: approach_replay.Prefix, rp: approach_replay.Replay) -> None:
        seen.append({"prefix": prefix, "replay": rp})
        original(self, prefix, rp)

    monkeypatch.setattr(rollout.Run, "resume", spy)
    return seen


@pytest.mark.parametrize(("name", "strategy", "condition"), [("box", "C", 1), ("apple", "S", 2), ("cylinder", "C", 1)])
def test_the_resumed_state_is_the_full_simulations(
    name: str, strategy: str, condition: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    obj = builtin_object(name)
    sr, st = TABLE1_CONDITIONS[condition]
    seed = trial_seed(3, (condition, 0, 0), 1)
    states: list[tuple[float, np.ndarray]] = []

    def every_tick(_scene: object, data: mujoco.MjData) -> None:
        states.append((float(data.time), data.qpos.copy()))

    run_trial(HAND, obj, strategy, seed=seed, sigma_r=sr, sigma_t=st, config=FULL, on_frame=every_tick,  # type: ignore[arg-type]
              frame_period=0.0099)  # fmt: skip
    seen = _resumes(monkeypatch)
    run_trial(HAND, obj, strategy, seed=seed, sigma_r=sr, sigma_t=st)  # type: ignore[arg-type]
    assert len(seen) == 1
    prefix, rp = seen[0]["prefix"], seen[0]["replay"]
    assert 50 <= rp.tick < prefix.n  # well into the approach, before the closure's end
    t, qpos = states[rp.tick]  # states[0] is the start, states[k] after tick k
    assert t == pytest.approx(prefix.time[rp.tick], abs=1e-9)
    scene = build_scene(HAND, obj)
    a = scene.object_qpos
    robot = np.ones(qpos.size, dtype=bool)
    robot[a : a + 7] = False
    np.testing.assert_array_equal(prefix.qpos[rp.tick][robot], qpos[robot])  # the robot: bit for bit
    np.testing.assert_allclose(rp.qpos, qpos[a : a + 7], rtol=0.0, atol=1e-9)  # the object: to rounding


@pytest.mark.parametrize(("name", "strategy", "seed"), [("box", "C", 4), ("apple", "S", 5), ("cylinder", "C", 6)])
def test_a_trial_resumes_just_before_the_robot_touches_the_object(
    name: str, strategy: str, seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The full simulation's first contact between the robot and the object comes after the resume tick, and the
    sharing reaches close to it (within a few ticks), past the approach's end when the fingers touch in the
    closure."""
    obj = builtin_object(name)
    touched: list[int] = []
    ticks = [0]

    def every_tick(scene: Any, data: mujoco.MjData) -> None:
        contacts = scene.contact_summary(data)
        if contacts.object_hand or contacts.arm_object:
            touched.append(ticks[0])
        ticks[0] += 1

    run_trial(HAND, obj, strategy, seed=seed, sigma_r=0.1, sigma_t=0.02, config=FULL, on_frame=every_tick,  # type: ignore[arg-type]
              frame_period=0.0099)  # fmt: skip
    seen = _resumes(monkeypatch)
    run_trial(HAND, obj, strategy, seed=seed, sigma_r=0.1, sigma_t=0.02)  # type: ignore[arg-type]
    prefix, rp = seen[0]["prefix"], seen[0]["replay"]
    assert touched, "the hand never touched the object"
    first = touched[0]  # the first tick after which the scene's contacts include one of the robot with the object
    assert rp.tick < first <= rp.tick + 5
    assert rp.tick > prefix.n_approach - 20  # at least into the approach's last fifth
    scene = build_scene(HAND, obj)
    data = mujoco.MjData(scene.model)
    data.qpos[:] = prefix.qpos[rp.tick]
    data.qpos[scene.object_qpos : scene.object_qpos + 7] = rp.qpos
    mujoco.mj_kinematics(scene.model, data)
    g_obj = int(scene.object_geoms[0])
    gap = min(mujoco.mj_geomDistance(scene.model, data, int(g), g_obj, 1.0, None) for g in prefix.geoms)
    assert gap > approach_replay.MARGIN  # nothing of the robot touches the object where the trial resumes


def test_an_object_out_of_reach_is_replayed_until_just_before_the_closure_ends(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A 30 cm offset puts the box beside the hand: never touched, it is replayed through the approach and the
    closure but the closure's last tick, and the verdict is the full simulation's."""
    obj = builtin_object("box")
    far = rollout.Perturbation(0.0, 0.3, 0.0)
    seen = _resumes(monkeypatch)
    fast = run_trial(HAND, obj, "S", seed=0, perturbation=far)
    full = run_trial(HAND, obj, "S", seed=0, perturbation=far, config=FULL)
    prefix, rp = seen[0]["prefix"], seen[0]["replay"]
    assert rp.tick == prefix.n - 1 and rp.approach_end is not None
    assert (fast.success, fast.reason) == (full.success, full.reason) == (False, "no_contact")
    shot, reference = fast.diagnosis["phases"][0], full.diagnosis["phases"][0]  # the approach's end, from the replay
    assert shot["hand_contacts"] == reference["hand_contacts"] == {} and shot["touches_table"]
    assert shot["height"] == pytest.approx(reference["height"], abs=1e-4)
    assert shot["offset"] == pytest.approx(reference["offset"], abs=1e-3)
    assert fast.settle_drop == pytest.approx(full.settle_drop, abs=1e-9)


def test_one_recording_serves_every_trial_of_a_plan(monkeypatch: pytest.MonkeyPatch) -> None:
    obj = builtin_object("apple")
    recorded: list[int] = []
    original = rollout.record_prefix

    def counting(*args: Any, **kwargs: Any) -> approach_replay.Prefix:
        recorded.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(rollout, "record_prefix", counting)
    monkeypatch.setattr(approach_replay, "_CACHE", approach_replay.weakref.WeakKeyDictionary())
    for seed in range(3):
        run_trial(HAND, obj, "S", seed=seed, sigma_r=0.1, sigma_t=0.01)
    assert len(recorded) == 1  # one plan (the nominal pose's), one recording
    run_trial(HAND, obj, "C", seed=0, sigma_r=0.1, sigma_t=0.01)
    assert len(recorded) == 2  # another plan, another recording


def test_frames_and_obstacles_simulate_everything(monkeypatch: pytest.MonkeyPatch) -> None:
    seen = _resumes(monkeypatch)
    run_trial(HAND, builtin_object("box"), "S", seed=0, on_frame=lambda _s, _d: None)
    obstacle = builtin_object("cylinder").with_pose(0.5, 0.25, 0.0)
    run_trial(HAND, builtin_object("box"), "S", seed=0, obstacles=[obstacle])
    assert seen == []
