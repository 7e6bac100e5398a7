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


def test_an_arm_link_on_an_obstacle_is_an_arm_contact() -> None:
    from softsig_service.arm.ur5 import HOME_Q, load_ur5
    from softsig_service.simulation.scene_model import GEOM_OBSTACLE

    T = load_ur5().frame_pose(np.array(HOME_Q), "forearm_link")
    on_forearm = box((0.06, 0.06, 0.06), 0.3, x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3]), yaw=0.0)
    scene = build_scene("parallel_gripper", TARGET, obstacles=(on_forearm, POST))
    assert len(scene.obstacle_geoms) >= 2 and set(scene.geom_class[scene.obstacle_geoms]) == {GEOM_OBSTACLE}
    data = scene.make_data(np.array(HOME_Q), TARGET.primitive_pose)
    contacts = scene.contact_summary(data)
    assert contacts.arm_obstacle and not contacts.arm_object and not contacts.arm_table
    clear = build_scene("parallel_gripper", TARGET, obstacles=(POST,))
    assert not clear.contact_summary(clear.make_data(np.array(HOME_Q), TARGET.primitive_pose)).arm_obstacle


def test_an_object_given_above_the_table_settles_and_is_judged_from_its_rest() -> None:
    from softsig_service.objects import object_from_json
    from softsig_service.simulation.rollout import SETTLE_DROP

    resting = run_trial("parallel_gripper", TARGET, "S", seed=0)
    assert resting.success and resting.settle_drop is not None and abs(resting.settle_drop) < SETTLE_DROP
    above = object_from_json({"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.0, "yaw": 0.0,
                                                                          "z": 0.025 + 0.03}})  # fmt: skip
    plan = default_planner().plan(PlanRequest(hand="parallel_gripper", obj=TARGET, strategy="S"))
    fell = run_trial("parallel_gripper", above, "S", seed=0, plan=plan)  # the grasp of where it comes to rest
    assert fell.settle_drop is not None and abs(fell.settle_drop - 0.03) < 0.003, fell.settle_drop
    assert fell.success and abs(fell.lift_height - resting.lift_height) < 0.003, (fell.lift_height, resting)
