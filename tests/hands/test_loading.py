"""Manifests, asset paths, size limits and a third-party URDF hand loaded without editing its files."""

from __future__ import annotations

import hashlib
import shutil
import struct
import textwrap
from pathlib import Path

import numpy as np
import pytest

from softsig_service.config import ModelLimits, Settings
from softsig_service.errors import (
    FrameNotFound,
    HandNotFound,
    InvalidManifest,
    ModelTooLarge,
    SoftsigError,
    UnsafePath,
)
from softsig_service.hands.closure import simulate_closure
from softsig_service.hands.manifest import load_manifest, manifest_from_dict
from softsig_service.hands.model import load_hand
from softsig_service.hands.summary import fingertip_spread

BASE = {
    "name": "h",
    "model": "h.xml",
    "mount": "mount",
    "closure": {"kind": "actuator", "actuators": ["a"], "open": 0.0, "closed": 1.0},
}


def _with(**changes: object) -> dict[str, object]:
    data = {**BASE}
    data.update(changes)
    return data


@pytest.mark.parametrize(
    ("data", "field", "choice"),
    [
        ({k: v for k, v in BASE.items() if k != "mount"}, "mount", None),
        (_with(closure={"kind": "pressure"}), "closure.kind", "posture"),
        (_with(colour="red"), "colour", "reference_points"),
        (_with(simulation={"integrator": "leapfrog"}), "simulation.integrator", "implicitfast"),
        (_with(simulation={"timestep": -1}), "simulation.timestep", None),
        (_with(model="h.obj"), "model", None),
        (_with(name="Bad Name"), "name", None),
        (_with(reference_points=[{"name": "a", "site": "s", "body": "b"}] * 4), "reference_points[0]", None),
        (
            _with(reference_points=[{"name": f"p{k}", "site": "s"} for k in range(3)]),
            "reference_points",
            None,
        ),
        (
            _with(closure={"kind": "posture", "open": {"j1": 0.0}, "closed": {"j2": 1.0}}),
            "closure",
            None,
        ),
        (_with(closure={**BASE["closure"], "duration": float("nan")}), "closure.duration", None),  # type: ignore[dict-item]
    ],
)
def test_bad_manifest_names_the_field(data: dict[str, object], field: str, choice: str | None) -> None:
    with pytest.raises(InvalidManifest) as info:
        manifest_from_dict(data)
    assert info.value.field == field
    if choice is not None:
        assert info.value.choices is not None and choice in info.value.choices
    assert field in str(info.value)


def test_manifest_that_is_not_toml(tmp_path: Path) -> None:
    path = tmp_path / "hand.toml"
    path.write_text("name = [unclosed\n")
    with pytest.raises(InvalidManifest, match="not valid TOML"):
        load_manifest(path)


def test_unknown_hand_lists_the_builtin_choices(settings: Settings) -> None:
    with pytest.raises(HandNotFound) as info:
        load_hand("no_such_hand", settings)
    assert info.value.choices is not None and "pisa_iit_softhand" in info.value.choices


def _copy_builtin(tmp_path: Path, name: str) -> Path:
    folder = tmp_path / name
    shutil.copytree(Path(Settings().hands_dir) / name, folder)
    return folder


def test_unknown_actuator_and_site_are_named(tmp_path: Path, settings: Settings) -> None:
    folder = _copy_builtin(tmp_path, "pisa_iit_softhand")
    toml = folder / "hand.toml"
    toml.write_text(toml.read_text().replace('actuators = ["synergy"]', 'actuators = ["motor"]'))
    with pytest.raises(FrameNotFound) as info:
        load_hand(str(toml), settings)
    assert info.value.field == "closure.actuators[0]" and info.value.choices == ["synergy"]
    toml.write_text(
        toml.read_text()
        .replace('actuators = ["motor"]', 'actuators = ["synergy"]')
        .replace('site = "ring_tip"', 'site = "ring_top"')
    )
    with pytest.raises(FrameNotFound) as info:
        load_hand(str(toml), settings)
    assert info.value.field == "reference_points[3].site"
    assert info.value.choices is not None and "ring_tip" in info.value.choices


# --- a user's MJCF with mesh files -------------------------------------------------------------------------


def write_box_stl(path: Path, half: tuple[float, float, float]) -> None:
    """A binary STL of an axis-aligned box centred at the origin (12 triangles)."""
    hx, hy, hz = half
    v = np.array([[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    faces = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4),
             (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]  # fmt: skip
    out = bytearray(b"\0" * 80 + struct.pack("<I", len(faces)))
    for a, b, c in faces:
        n = np.cross(v[b] - v[a], v[c] - v[a])
        n = n / np.linalg.norm(n)
        out += struct.pack("<12fH", *n, *v[a], *v[b], *v[c], 0)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(bytes(out))


MJCF_WITH_MESH = """
<mujoco>
  <compiler angle="radian" autolimits="true" meshdir="{meshdir}"/>
  <asset><mesh name="palm" file="{file}"/></asset>
  <worldbody>
    <body name="mount">
      <geom type="mesh" mesh="palm"/>
      <body name="f1" pos="0.03 0 0.05"><joint name="j1" axis="0 1 0" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.05" size="0.008"/><site name="a_tip" pos="0 0 0.05"/></body>
      <body name="f2" pos="-0.03 0 0.05"><joint name="j2" axis="0 -1 0" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.05" size="0.008"/><site name="b_tip" pos="0 0 0.05"/></body>
      <body name="f3" pos="0 0.03 0.05"><joint name="j3" axis="1 0 0" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.05" size="0.008"/><site name="c_tip" pos="0 0 0.05"/></body>
      <site name="wrist" pos="0 0 0"/>
    </body>
  </worldbody>
</mujoco>
"""

POSTURE = """
name = "user_hand"
model = "{model}"
mount = "{mount}"
{points}
[closure]
kind = "posture"
open = {{ {open} }}
closed = {{ {closed} }}
kp = 20.0
kv = 1.0
"""


def _user_mjcf(tmp_path: Path, meshdir: str, file: str) -> Path:
    folder = tmp_path / "hand"
    folder.mkdir(exist_ok=True)
    (folder / "hand.xml").write_text(MJCF_WITH_MESH.format(meshdir=meshdir, file=file))
    (folder / "hand.toml").write_text(
        POSTURE.format(
            model="hand.xml",
            mount="mount",
            points="",
            open="j1 = 0.0, j2 = 0.0, j3 = 0.0",
            closed="j1 = -0.8, j2 = -0.8, j3 = 0.8",
        )
    )
    return folder / "hand.toml"


def test_user_mjcf_with_mesh_loads_and_closes(tmp_path: Path, settings: Settings) -> None:
    toml = _user_mjcf(tmp_path, "meshes", "palm.stl")
    write_box_stl(tmp_path / "hand" / "meshes" / "palm.stl", (0.04, 0.02, 0.02))
    hand = load_hand(str(toml), settings)
    assert hand.point_names == ("a_tip", "b_tip", "c_tip", "wrist")  # default: *_tip sites + wrist
    traj = simulate_closure(hand)
    assert traj.surface is not None
    assert fingertip_spread(traj.positions[-1], traj.point_names) < 0.7 * fingertip_spread(
        traj.positions[0], traj.point_names
    )


@pytest.mark.parametrize(
    ("meshdir", "file"),
    [
        ("meshes", "/etc/hostname"),
        ("meshes", "../../outside.stl"),
        ("/tmp", "palm.stl"),
        ("..", "palm.stl"),
        ("meshes", "file:///etc/hostname"),
    ],
)
def test_mjcf_paths_leaving_the_folder_are_rejected(
    tmp_path: Path, settings: Settings, meshdir: str, file: str
) -> None:
    toml = _user_mjcf(tmp_path, meshdir, file)
    write_box_stl(tmp_path / "outside.stl", (0.01, 0.01, 0.01))
    with pytest.raises(UnsafePath):
        load_hand(str(toml), settings)


def test_symlink_out_of_the_folder_is_rejected(tmp_path: Path, settings: Settings) -> None:
    toml = _user_mjcf(tmp_path, "meshes", "palm.stl")
    write_box_stl(tmp_path / "secret.stl", (0.01, 0.01, 0.01))
    (tmp_path / "hand" / "meshes").mkdir()
    (tmp_path / "hand" / "meshes" / "palm.stl").symlink_to(tmp_path / "secret.stl")
    with pytest.raises(UnsafePath):
        load_hand(str(toml), settings)


def test_oversized_mesh_and_model_are_rejected(tmp_path: Path) -> None:
    toml = _user_mjcf(tmp_path, "meshes", "palm.stl")
    write_box_stl(tmp_path / "hand" / "meshes" / "palm.stl", (0.04, 0.02, 0.02))
    small = Settings(limits=ModelLimits(max_asset_bytes=100))
    with pytest.raises(ModelTooLarge) as info:
        load_hand(str(toml), small)
    assert "mesh" in str(info.value.field)
    with pytest.raises(ModelTooLarge):
        load_hand(str(toml), Settings(limits=ModelLimits(max_dofs=2)))
    with pytest.raises(ModelTooLarge):
        load_hand(str(toml), Settings(limits=ModelLimits(max_model_bytes=200)))


# --- a third-party URDF hand with STL meshes in a ROS-style package layout ----------------------------------

URDF = """<?xml version="1.0"?>
<robot name="two_jaw">
  <link name="base_link">
    <inertial><mass value="0.3"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="package://two_jaw_description/meshes/visual/base.dae"/></geometry></visual>
    <collision><origin xyz="0 0 0.03"/>
      <geometry><mesh filename="package://two_jaw_description/meshes/collision/base.stl"/></geometry></collision>
  </link>
  <link name="left_jaw">
    <inertial><mass value="0.05"/><inertia ixx="1e-5" iyy="1e-5" izz="1e-5" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.03"/><geometry><mesh filename="meshes/collision/jaw.stl"/></geometry></collision>
  </link>
  <link name="right_jaw">
    <inertial><mass value="0.05"/><inertia ixx="1e-5" iyy="1e-5" izz="1e-5" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.03"/><geometry><mesh filename="meshes/collision/jaw.stl"/></geometry></collision>
  </link>
  <joint name="left_slide" type="prismatic">
    <parent link="base_link"/><child link="left_jaw"/><origin xyz="0 0.045 0.06"/>
    <axis xyz="0 1 0"/><limit lower="-0.04" upper="0.0" effort="50" velocity="0.2"/>
  </joint>
  <joint name="right_slide" type="prismatic">
    <parent link="base_link"/><child link="right_jaw"/><origin xyz="0 -0.045 0.06"/>
    <axis xyz="0 -1 0"/><limit lower="-0.04" upper="0.0" effort="50" velocity="0.2"/>
  </joint>
</robot>
"""


def test_third_party_urdf_hand_round_trip(tmp_path: Path, settings: Settings) -> None:
    folder = tmp_path / "two_jaw_description"
    (folder / "urdf").mkdir(parents=True)
    urdf = folder / "urdf" / "two_jaw.urdf"
    urdf.write_text(URDF)
    # package:// meshes resolve inside the package folder; plain relative ones beside the URDF
    write_box_stl(folder / "meshes" / "collision" / "base.stl", (0.04, 0.06, 0.03))
    write_box_stl(folder / "urdf" / "meshes" / "collision" / "jaw.stl", (0.01, 0.005, 0.03))
    before = hashlib.sha256(urdf.read_bytes()).hexdigest()
    points = textwrap.dedent(
        """
        reference_points = [
          { name = "left_tip", body = "left_jaw", offset = [0.0, 0.0, 0.06] },
          { name = "right_tip", body = "right_jaw", offset = [0.0, 0.0, 0.06] },
          { name = "left_base", body = "left_jaw", offset = [0.0, 0.0, 0.0] },
          { name = "right_base", body = "right_jaw", offset = [0.0, 0.0, 0.0] },
          { name = "wrist", body = "base_link" },
        ]
        """
    )
    toml = folder / "urdf" / "hand.toml"
    # the manifest lives beside the URDF; the package root is its parent, so point the loader there
    toml = folder / "hand.toml"
    toml.write_text(
        POSTURE.format(
            model="urdf/two_jaw.urdf",
            mount="base_link",
            points=points,
            open="left_slide = 0.0, right_slide = 0.0",
            closed="left_slide = -0.04, right_slide = -0.04",
        )
    )
    with pytest.raises(SoftsigError):
        # the jaw mesh is referenced relative to the URDF's folder; until it exists there, loading fails
        shutil.move(folder / "urdf" / "meshes", tmp_path / "moved")
        load_hand(str(toml), settings)
    shutil.move(tmp_path / "moved", folder / "urdf" / "meshes")
    hand = load_hand(str(toml), settings)
    assert hand.manifest.model_format == "urdf"
    traj = simulate_closure(hand)
    gap_open = np.linalg.norm(traj.positions[0, 0] - traj.positions[0, 1])
    gap_closed = np.linalg.norm(traj.positions[-1, 0] - traj.positions[-1, 1])
    assert gap_open == pytest.approx(0.09, abs=1e-6)
    assert gap_closed == pytest.approx(0.01, abs=2e-3)
    assert hashlib.sha256(urdf.read_bytes()).hexdigest() == before  # the URDF was not edited


@pytest.mark.parametrize("model", ["../elsewhere/hand.xml", "/etc/hand.xml"])
def test_model_file_outside_the_folder_is_rejected(tmp_path: Path, settings: Settings, model: str) -> None:
    toml = _user_mjcf(tmp_path, "meshes", "palm.stl")
    toml.write_text(toml.read_text().replace('model = "hand.xml"', f'model = "{model}"'))
    with pytest.raises(UnsafePath) as info:
        load_hand(str(toml), settings)
    assert info.value.field == "model"


@pytest.mark.parametrize("ref", ["package://two_jaw_description/../../../etc/x.stl", "/etc/x.stl"])
def test_urdf_mesh_escape_is_rejected(tmp_path: Path, settings: Settings, ref: str) -> None:
    folder = tmp_path / "h"
    folder.mkdir()
    (folder / "h.urdf").write_text(URDF.replace("package://two_jaw_description/meshes/collision/base.stl", ref))
    (folder / "hand.toml").write_text(
        POSTURE.format(
            model="h.urdf", mount="base_link", points="", open="left_slide = 0.0", closed="left_slide = -0.04"
        )
    )
    with pytest.raises(UnsafePath):
        load_hand(str(folder / "hand.toml"), settings)
