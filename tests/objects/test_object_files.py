"""Objects from files, read with trimesh and pypcd4: STL (binary and ASCII), OBJ and PLY meshes with a scale, PLY
and PCD clouds (NaN points of an organised cloud left out), each giving the object it holds; malformed, empty and
unknown files are refused naming the field; the CLI plans a mesh file as the JSON mesh."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

from softsig_service.cli import app
from softsig_service.errors import InvalidInput
from softsig_service.objects import object_from_json
from softsig_service.objects.files import object_from_file

BOX_MM = (160.0, 60.0, 50.0)


def _mesh_bytes(file_type: str) -> bytes:
    box = trimesh.creation.box(extents=BOX_MM)
    if file_type == "stl_ascii":
        return trimesh.exchange.stl.export_stl_ascii(box).encode()
    data = box.export(file_type=file_type)
    return data if isinstance(data, bytes) else data.encode()


@pytest.mark.parametrize(("file_type", "suffix"), [("stl", ".stl"), ("stl_ascii", ".stl"), ("obj", ".obj"),
                                                   ("ply", ".ply")])  # fmt: skip
def test_a_mesh_file_in_millimetres_is_the_box_it_holds(file_type: str, suffix: str) -> None:
    spec = object_from_file(_mesh_bytes(file_type), f"box{suffix}", mass=0.15, scale=0.001)
    assert spec["kind"] == "mesh" and spec["name"] == "box"
    obj = object_from_json({**spec, "pose": {"x": 0.5, "y": 0.0, "yaw": 0.3}})
    assert (obj.extent_major, obj.extent_minor, obj.height) == pytest.approx((0.16, 0.06, 0.05), abs=1e-12)
    assert obj.yaw == 0.3


def _cloud_points(n: int = 500) -> np.ndarray:
    rng = np.random.default_rng(0)
    return np.c_[rng.uniform(0.45, 0.55, n), rng.uniform(-0.03, 0.03, n), rng.uniform(0.0, 0.05, n)]


def test_a_ply_cloud_and_a_pcd_cloud_are_point_objects(tmp_path: Path) -> None:
    from pypcd4 import PointCloud

    points = _cloud_points()
    ply = trimesh.PointCloud(points).export(file_type="ply")
    organised = np.vstack([points, np.full((20, 3), np.nan)]).astype(np.float32)  # pixels without depth
    PointCloud.from_xyz_points(organised).save(tmp_path / "scan.pcd")
    for spec in (object_from_file(ply, "scan.ply", mass=0.1, frame_id="camera_depth_optical_frame"),
                 object_from_file((tmp_path / "scan.pcd").read_bytes(), "scan.pcd", mass=0.1,
                                  frame_id="camera_depth_optical_frame")):  # fmt: skip
        assert spec["kind"] == "points" and spec["frame_id"] == "camera_depth_optical_frame"
        assert len(spec["points"]) == len(points)
        assert np.allclose(spec["points"], points, atol=1e-6)  # the PCD stores float32


@pytest.mark.parametrize(
    ("data", "name", "field"),
    [
        (b"", "x.stl", "file"),
        (b"solid x\nendsolid x\n", "x.stl", "file"),
        (b"not a mesh at all", "x.obj", "file"),
        (b"# .PCD v0.7\nFIELDS a b\n", "x.pcd", "file"),
        (b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
         b"end_header\n0 0 0\n1 1 1\n", "x.ply", "file"),
        (b"whatever", "x.step", "file"),
    ],
)  # fmt: skip
def test_bad_files_are_refused_naming_the_field(data: bytes, name: str, field: str) -> None:
    with pytest.raises(InvalidInput) as info:
        object_from_file(data, name, mass=0.1)
    assert info.value.field == field


def test_the_cli_plans_a_mesh_file_as_the_same_mesh_in_json(tmp_path: Path) -> None:
    stl = tmp_path / "box.stl"
    stl.write_bytes(_mesh_bytes("stl"))
    spec = object_from_file(stl.read_bytes(), "box.stl", mass=0.15, scale=0.001)
    (tmp_path / "box.json").write_text(json.dumps(spec), encoding="utf-8")
    runner = CliRunner()
    common = ["plan", "--hand", "parallel_gripper", "--strategy", "S", "--json"]
    from_file = runner.invoke(app, [*common, "--object", str(stl), "--mass", "0.15", "--scale", "0.001"])
    from_json = runner.invoke(app, [*common, "--object", str(tmp_path / "box.json")])
    assert from_file.exit_code == 0, from_file.output
    assert json.loads(from_file.output)["grasp_pose"] == json.loads(from_json.output)["grasp_pose"]
    missing = runner.invoke(app, [*common, "--object", str(stl)])
    assert missing.exit_code != 0 and "--mass" in missing.output
