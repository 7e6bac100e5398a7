"""A plan's grasps as moveit_msgs/Grasp: every grasp's ``moveit_grasp`` (and its trajectories) is built into the
real ROS 2 message with rosbags' typestore (the standard types plus moveit_msgs' Grasp and GripperTranslation
registered from their definitions), serialised to CDR, read back and found equal to the JSON it came from."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import Nodetype

from softsig_service.experiments.trial import default_planner
from softsig_service.objects import builtin_object
from softsig_service.planning.request import PlanRequest

MSG_DIR = Path(__file__).resolve().parents[1] / "data" / "moveit_msgs" / "msg"
DTYPES = {"float64": np.float64, "float32": np.float32, "int32": np.int32, "uint32": np.uint32, "uint8": np.uint8}


@pytest.fixture(scope="module")
def typestore() -> Any:
    store = get_typestore(Stores.ROS2_HUMBLE)
    types: dict[str, Any] = {}
    for name in ("GripperTranslation", "Grasp"):
        types.update(get_types_from_msg((MSG_DIR / f"{name}.msg").read_text(), f"moveit_msgs/msg/{name}"))
    store.register(types)
    return store


def _build(store: Any, typename: str, value: dict[str, Any]) -> Any:
    """The rosbags message ``typename`` of the JSON ``value``: every field the definition has, and no other."""
    _, fields = store.fielddefs[typename]
    assert set(value) == {name for name, _ in fields}, (typename, set(value) ^ {name for name, _ in fields})
    return store.types[typename](
        **{name: _convert(store, kind, detail, value[name]) for name, (kind, detail) in fields}
    )


def _convert(store: Any, kind: Nodetype, detail: Any, value: Any) -> Any:
    if kind == Nodetype.BASE:
        return str(value) if detail[0] == "string" else DTYPES[detail[0]](value).item()
    if kind == Nodetype.NAME:
        return _build(store, detail, value)
    (sub_kind, sub_detail), _ = detail
    if sub_kind == Nodetype.BASE and sub_detail[0] != "string":
        return np.asarray(value, dtype=DTYPES[sub_detail[0]])
    return [_convert(store, sub_kind, sub_detail, v) for v in value]


def _plain(message: Any) -> Any:
    """A rosbags message as plain JSON-like data."""
    if hasattr(message, "__dataclass_fields__"):
        return {k: _plain(getattr(message, k)) for k in message.__dataclass_fields__ if k != "__msgtype__"}
    if isinstance(message, np.ndarray):
        return message.tolist()
    if isinstance(message, list):
        return [_plain(v) for v in message]
    return message


def _assert_equal(a: Any, b: Any, path: str = "") -> None:
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            _assert_equal(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_equal(x, y, f"{path}[{i}]")
    elif isinstance(a, float):
        assert b == pytest.approx(a, rel=1e-6, abs=1e-7), path  # float32 fields keep 7 digits
    else:
        assert a == b, path


@pytest.mark.parametrize(("hand", "strategy"), [("pisa_iit_softhand", "C"), ("parallel_gripper", "S")])
def test_every_grasp_is_the_message_and_survives_cdr(typestore: Any, hand: str, strategy: str) -> None:
    plan = default_planner().plan(PlanRequest(hand=hand, obj=builtin_object("box"), strategy=strategy, candidates=3))
    data = plan.to_json_dict()
    assert plan.success and len(data["grasps"]) == 3
    for grasp in data["grasps"]:
        for typename, value in (("moveit_msgs/msg/Grasp", grasp["moveit_grasp"]),
                                ("trajectory_msgs/msg/JointTrajectory", grasp["approach_trajectory"]),
                                ("trajectory_msgs/msg/JointTrajectory", grasp["retreat_trajectory"])):  # fmt: skip
            message = _build(typestore, typename, value)
            raw = typestore.serialize_cdr(message, typename)
            back = typestore.deserialize_cdr(raw, typename)
            _assert_equal(value, _plain(back))
        msg = grasp["moveit_grasp"]
        assert msg["grasp_quality"] == grasp["grasp_quality"] and msg["id"] == grasp["id"]
        assert msg["grasp_pose"]["pose"]["position"] == grasp["grasp_pose"]["position"]
        assert msg["grasp_posture"]["joint_names"] == plan.closure["commands"]
        assert msg["grasp_posture"]["points"][0]["positions"] == plan.closure["closed"]
        assert msg["post_grasp_retreat"]["direction"]["vector"] == {"x": 0.0, "y": 0.0, "z": 1.0}
    expected = {"pisa_iit_softhand": ["synergy"], "parallel_gripper": ["left_jaw", "right_jaw"]}[hand]
    assert plan.closure["commands"] == expected  # the gripper's jaws by their joints, not softsig's servos
