"""Obstacles in the validation scene: free bodies at their poses that rest on the table, and that a hand planned
without knowing of them pushes aside; the planner, told of them, goes around (the trial then leaves them be)."""

from __future__ import annotations

import mujoco
import numpy as np

from softsig_service.experiments.trial import default_planner, run_trial
from softsig_service.objects import box, builtin_object
from softsig_service.planning.request import PlanRequest
from softsig_service.simulation.scene import build_scene

TARGET = builtin_object("box", x=0.5, y=0.0, yaw=0.0)
POST = box((0.10, 0.04, 0.12), 0.3, x=0.5, y=0.06, yaw=0.0)  # in the gripper's jaw, beside the box


def _track(hand: str, obstacle_far: bool, plan_knows: bool) -> tuple[float, object]:
    """The trial's largest displacement [m] of the obstacle from its start, and the trial."""
    post = box((0.10, 0.04, 0.12), 0.3, x=0.5, y=0.6, yaw=0.0) if obstacle_far else POST
    start = post.primitive_pose[:3, 3]
    moved = [0.0]

    def on_frame(scene: object, data: mujoco.MjData) -> None:
        body = scene.model.body("obstacle_0").id  # type: ignore[attr-defined]
        moved[0] = max(moved[0], float(np.linalg.norm(data.xpos[body] - start)))

    plan = None
    if not plan_knows:
        plan = default_planner().plan(PlanRequest(hand=hand, obj=TARGET, strategy="S"))
    result = run_trial(hand, TARGET, "S", seed=0, plan=plan, obstacles=(post,), on_frame=on_frame, frame_period=0.02)
    return moved[0], result


def test_an_obstacle_rests_where_it_is_put() -> None:
    scene = build_scene("parallel_gripper", TARGET, obstacles=(POST,))
    data = scene.make_data(np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0]), TARGET.primitive_pose)
    body = scene.model.body("obstacle_0").id
    assert np.allclose(data.xpos[body], POST.primitive_pose[:3, 3], atol=1e-9)
    for _ in range(int(0.5 / scene.model.opt.timestep)):
        mujoco.mj_step(scene.model, data)
    assert np.linalg.norm(data.xpos[body] - POST.primitive_pose[:3, 3]) < 0.002  # settles on the table


def test_a_hand_planned_blind_pushes_the_obstacle_and_a_told_planner_refuses() -> None:
    pushed, _ = _track("parallel_gripper", obstacle_far=False, plan_knows=False)
    assert pushed > 0.005, pushed  # the jaw came down on it or closed against it
    _, told = _track("parallel_gripper", obstacle_far=False, plan_knows=True)
    assert not told.success and told.reason == "collision:obstacle[0]"  # type: ignore[attr-defined]
    still, far = _track("parallel_gripper", obstacle_far=True, plan_knows=True)
    assert still < 0.002 and far.success, (still, far)  # type: ignore[attr-defined]
