"""The flange and the grasp frame are two frames: the same gripper mounted straight on the flange and on a bracket
(a 60 mm spacer turned a quarter turn about the tool axis), its manifest stating where the grasp frame is, has the
same closure signature in the grasp frame and the same grasp-frame plan, with other flange poses and arm joints,
which MuJoCo's kinematics of the URDF (independent of Pinocchio's) confirm; the validation carries the object with
both."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from softsig_service.experiments.trial import default_planner, run_trial
from softsig_service.objects import builtin_object
from softsig_service.planning.hand_model import planning_model
from softsig_service.planning.request import PlanRequest
from softsig_service.simulation.scene import build_scene

BOX = builtin_object("box")
BUILTIN = Path(__file__).resolve().parents[2] / "hands" / "parallel_gripper"


def write_gripper_on_bracket(folder: Path) -> str:
    """Write into ``folder`` the parallel gripper with its flange frame 60 mm behind the description's mount frame,
    turned pi/2 about z, and the grasp frame back at the description's mount frame; return its manifest's path."""
    shutil.copytree(BUILTIN, folder)
    text = (folder / "hand.toml").read_text()
    text = text.replace('name = "parallel_gripper"', 'name = "gripper_on_bracket"')
    text = text.replace('mount = "mount"\n', 'mount = "mount"\n'
                        f"mount_pose = {{ xyz = [0.0, 0.0, -0.06], rpy = [0.0, 0.0, {math.pi / 2!r}] }}\n"
                        f"grasp_frame = {{ xyz = [0.0, 0.0, 0.06], rpy = [0.0, 0.0, {-math.pi / 2!r}] }}\n")  # fmt: skip
    (folder / "hand.toml").write_text(text)
    return str(folder / "hand.toml")


@pytest.fixture(scope="module")
def bracketed(tmp_path_factory: pytest.TempPathFactory) -> str:
    """The gripper on its bracket (``write_gripper_on_bracket``)."""
    return write_gripper_on_bracket(tmp_path_factory.mktemp("hands") / "gripper_on_bracket")


def test_the_signature_and_the_points_are_the_same_in_the_grasp_frame(bracketed: str) -> None:
    straight, bracket = planning_model("parallel_gripper"), planning_model(bracketed)
    assert np.allclose(straight.points_open, bracket.points_open, atol=1e-9)
    assert np.allclose(straight.signature.axis, bracket.signature.axis, atol=1e-9)
    assert not np.allclose(bracket.grasp_in_flange, np.eye(4))
    for a, b in zip(straight.shapes, bracket.shapes, strict=True):
        assert np.allclose(a.pose_in_hand, b.pose_in_hand, atol=1e-9)


@pytest.mark.parametrize("strategy", ["S", "C"])
def test_the_same_grasp_frame_pose_from_other_joints_and_the_same_verdict(bracketed: str, strategy: str) -> None:
    planner = default_planner()
    plans = {}
    for ref in ("parallel_gripper", bracketed):
        plans[ref] = planner.plan(PlanRequest(hand=ref, obj=BOX, strategy=strategy))  # type: ignore[arg-type]
        assert plans[ref].success, plans[ref].reasons
    a, b = plans["parallel_gripper"], plans[bracketed]
    # the grasp-frame pose is one of the straight mount's two yaw branches (each picks the branch nearest its arm)
    branches = default_planner().plan(PlanRequest(hand="parallel_gripper", obj=BOX, strategy=strategy, candidates=2))  # type: ignore[arg-type]
    assert len(branches.grasps) == 2
    match = [g for g in branches.grasps if np.allclose(g["grasp_frame_pose"], b.grasp_frame_pose, atol=1e-6)]
    assert len(match) == 1
    a_g = match[0]
    assert not np.allclose(a_g["grasp_pose"], b.grasp_pose, atol=1e-3)  # the flanges differ by the bracket
    assert np.max(np.abs(np.subtract(a_g["joint_positions"], b.joint_positions))) > 0.05
    T_HG = planning_model(bracketed).grasp_in_flange
    scene = build_scene(bracketed, BOX)
    data = scene.make_data(np.array(b.joint_positions), BOX.primitive_pose)
    assert np.allclose(scene.flange_pose(data), b.grasp_pose, atol=1e-5)  # MuJoCo's FK of the joints
    assert np.allclose(scene.flange_pose(data) @ T_HG, a_g["grasp_frame_pose"], atol=1e-5)
    assert a.success
    verdicts = [run_trial(ref, BOX, strategy, seed=0).success for ref in ("parallel_gripper", bracketed)]  # type: ignore[arg-type]
    assert verdicts[0] == verdicts[1], verdicts
