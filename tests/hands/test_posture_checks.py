"""A posture closure that cannot work is refused at load, naming the joint: a hinge left without a servo target, a
target outside its joint's range, an angle that is most likely in degrees; an object's yaw likewise."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_loading import MJCF_WITH_MESH, POSTURE, write_box_stl

from softsig_service.config import Settings
from softsig_service.errors import InvalidHandModel, InvalidInput
from softsig_service.hands.model import load_hand
from softsig_service.objects import builtin_object


def _hand(tmp_path: Path, open_: str, closed: str) -> str:
    folder = tmp_path / "hand"
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    write_box_stl(folder / "meshes" / "palm.stl", (0.04, 0.02, 0.02))
    (folder / "hand.xml").write_text(MJCF_WITH_MESH.format(meshdir="meshes", file="palm.stl"))
    (folder / "hand.toml").write_text(
        POSTURE.format(model="hand.xml", mount="mount", points="", open=open_, closed=closed)
    )
    return str(folder / "hand.toml")


ALL_OPEN = "j1 = 0.0, j2 = 0.0, j3 = 0.0"


def test_a_complete_posture_within_the_ranges_loads(tmp_path: Path, settings: Settings) -> None:
    hand = load_hand(_hand(tmp_path, ALL_OPEN, "j1 = -0.8, j2 = -0.8, j3 = 0.8"), settings)
    assert len(hand.closure_actuators) == 3


@pytest.mark.parametrize(
    ("open_", "closed", "field", "words"),
    [
        ("j1 = 0.0, j2 = 0.0", "j1 = -0.8, j2 = -0.8", "closure.open", "'j3' without a servo target"),
        (ALL_OPEN, "j1 = -0.8, j2 = -1.2, j3 = 0.8", "closure.closed.j2", "outside the joint's range [-1, 1]"),
        (ALL_OPEN, "j1 = -0.8, j2 = -0.8, j3 = 30.0", "closure.closed.j3", "degrees"),
    ],
)
def test_a_posture_that_cannot_work_is_refused(
    tmp_path: Path, settings: Settings, open_: str, closed: str, field: str, words: str
) -> None:
    with pytest.raises(InvalidHandModel) as info:
        load_hand(_hand(tmp_path, open_, closed), settings)
    assert info.value.field == field and words in info.value.message, (info.value.field, info.value.message)


def test_an_object_yaw_in_degrees_is_refused() -> None:
    assert builtin_object("box", yaw=-6.28).yaw == -6.28
    with pytest.raises(InvalidInput, match=r"6\.283") as info:
        builtin_object("box", yaw=30.0)
    assert info.value.field == "object.pose.yaw"
