"""The object registry: an object registered once (JSON, a camera-frame cloud, a mesh file) is planned by id as its
geometry sent inline is, at another pose, with another mass; listed, read and deleted; unknown ids and bad files are
refused naming the field, and nothing is stored on a refusal."""

from __future__ import annotations

from typing import Any

import numpy as np
import trimesh
from api_helpers import AUTH, assert_problem
from fastapi.testclient import TestClient

MESH_MM = trimesh.creation.box(extents=(160.0, 60.0, 50.0))


def _plan(api: TestClient, obj: dict[str, Any]) -> dict[str, Any]:
    r = api.post("/v1/plans", json={"hand": "parallel_gripper", "object": obj, "strategy": "S", "store": False},
                 headers=AUTH)  # fmt: skip
    assert r.status_code == 200, r.text
    return dict(r.json())


def _position(plan: dict[str, Any]) -> np.ndarray:
    p = plan["grasp_pose"]["position"]
    return np.array([p["x"], p["y"], p["z"]])


def test_a_registered_cloud_plans_by_id_as_it_does_inline(api: TestClient) -> None:
    rng = np.random.default_rng(0)
    top = np.c_[rng.uniform(0.42, 0.58, 3000), rng.uniform(-0.03, 0.03, 3000), np.full(3000, 0.05)]
    corners = np.array([[x, y, 0.05] for x in (0.42, 0.58) for y in (-0.03, 0.03)])
    cloud = {"kind": "points", "points": np.vstack([top, corners]).tolist(), "mass": 0.15, "filter_outliers": False}
    r = api.post("/v1/objects", json={"object": cloud, "name": "seen box"}, headers=AUTH)
    assert r.status_code == 201, r.text
    rec = r.json()
    assert r.headers["location"] == f"/v1/objects/{rec['id']}" and rec["source"] == "points"
    assert (
        rec["object"]["kind"] == "mesh" and abs(rec["extent_major"] - 0.16) < 1e-9 and abs(rec["height"] - 0.05) < 1e-9
    )
    inline = _plan(api, cloud)
    by_id = _plan(api, {"kind": "stored", "id": rec["id"]})
    assert np.linalg.norm(_position(inline) - _position(by_id)) < 1e-9
    moved = _plan(api, {"kind": "stored", "id": rec["id"], "pose": {"x": 0.45, "y": 0.1, "yaw": 0.5}, "mass": 0.3})
    assert moved["success"] and abs(moved["object"]["pose"]["y"] - 0.1) < 1e-12 and moved["object"]["mass"] == 0.3
    assert api.get(f"/v1/objects/{rec['id']}").json()["name"] == "seen box"
    listed = api.get("/v1/objects").json()
    assert any(o["id"] == rec["id"] for o in listed["items"]) and "object" not in listed["items"][0]
    assert api.delete(f"/v1/objects/{rec['id']}", headers=AUTH).status_code == 204
    assert_problem(api.get(f"/v1/objects/{rec['id']}"), 404)
    body = {"hand": "parallel_gripper", "object": {"kind": "stored", "id": rec["id"]}, "strategy": "S"}
    assert assert_problem(api.post("/v1/plans", json=body, headers=AUTH), 422)["field"] == "object.id"


def test_a_mesh_file_in_millimetres_registers_and_plans(api: TestClient) -> None:
    stl = MESH_MM.export(file_type="stl")
    r = api.post("/v1/objects", files={"file": ("box.stl", stl)},
                 data={"mass": "0.15", "scale": "0.001"}, headers=AUTH)  # fmt: skip
    assert r.status_code == 201, r.text
    rec = r.json()
    assert rec["source"] == "stl" and rec["name"] == "box"
    assert (rec["extent_major"], rec["extent_minor"], rec["height"]) == (0.16, 0.06, 0.05)
    as_box = _plan(api, {"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15})
    by_id = _plan(api, {"kind": "stored", "id": rec["id"]})
    assert np.linalg.norm(_position(as_box) - _position(by_id)) < 1e-6


def test_refusals_name_the_field_and_store_nothing(api: TestClient) -> None:
    before = api.get("/v1/objects").json()["total"]
    bad = api.post("/v1/objects", files={"file": ("x.stl", b"nonsense")}, data={"mass": "0.1"}, headers=AUTH)
    assert assert_problem(bad, 422)["field"] == "file"
    step = api.post("/v1/objects", files={"file": ("x.step", b"ISO-10303")}, data={"mass": "0.1"}, headers=AUTH)
    assert assert_problem(step, 422)["field"] == "file"
    frames = api.post("/v1/objects", files={"file": ("box.stl", MESH_MM.export(file_type="stl"))},
                      data={"mass": "0.1", "frames": "{not json"}, headers=AUTH)  # fmt: skip
    assert assert_problem(frames, 422)["field"] == "frames"
    flat = {"kind": "points", "mass": 0.1, "points": [[0.5 + 0.01 * k, 0.01 * (k % 3), 0.0] for k in range(30)]}
    assert assert_problem(api.post("/v1/objects", json={"object": flat}, headers=AUTH), 422)["field"] == "object.points"
    stored = {"kind": "stored", "id": "0" * 32}
    assert assert_problem(api.post("/v1/objects", json={"object": stored}, headers=AUTH), 422)["field"] == "object.kind"
    assert api.get("/v1/objects").json()["total"] == before


def test_out_of_range_files_are_422_not_500(api: TestClient) -> None:
    stl = MESH_MM.export(file_type="stl")
    in_mm = api.post("/v1/objects", files={"file": ("box.stl", stl)}, data={"mass": "0.15"}, headers=AUTH)
    assert assert_problem(in_mm, 422)["field"].startswith("file.vertices[")  # 160 m long without scale 0.001
    light = api.post("/v1/objects", files={"file": ("box.stl", stl)}, data={"mass": "0.00001", "scale": "0.001"},
                     headers=AUTH)  # fmt: skip
    assert assert_problem(light, 422)["field"] == "mass"
    two = trimesh.util.concatenate([trimesh.creation.box(extents=(0.05, 0.05, 0.05)),
                                    trimesh.creation.box(extents=(0.05, 0.05, 0.05)).apply_translation((0.1, 0, 0))])  # fmt: skip
    scene = trimesh.Scene([trimesh.creation.box(extents=(0.05, 0.05, 0.05)),
                           trimesh.creation.box(extents=(0.05, 0.05, 0.05)).apply_translation((0.1, 0, 0))])  # fmt: skip
    solids = "".join(trimesh.exchange.stl.export_stl_ascii(g) for g in scene.dump())  # two solids in one file
    r = api.post("/v1/objects", files={"file": ("two.stl", solids.encode())}, data={"mass": "0.2"}, headers=AUTH)
    assert r.status_code == 201, r.text
    assert abs(r.json()["extent_major"] - 0.15) < 1e-9 and two is not None


def test_a_stored_object_stands_on_its_registered_table(api: TestClient) -> None:
    box = {"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15, "pose": {"x": 0.5, "y": 0.0}}
    r = api.post("/v1/objects", json={"object": box, "table": {"height": -0.08}}, headers=AUTH)
    assert r.status_code == 201, r.text
    plan = _plan(api, {"kind": "stored", "id": r.json()["id"]})
    on_zero = api.post("/v1/plans", json={"hand": "parallel_gripper", "strategy": "S", "store": False,
                                          "object": {"kind": "stored", "id": r.json()["id"]},
                                          "table": {"height": 0.0}}, headers=AUTH).json()  # fmt: skip
    assert abs(plan["grasp_pose"]["position"]["z"] - on_zero["grasp_pose"]["position"]["z"] + 0.08) < 1e-6


def test_a_household_mesh_is_planned_by_name_and_an_unknown_one_is_422(api: TestClient) -> None:
    plan = _plan(api, {"kind": "builtin", "name": "mug", "pose": {"x": 0.5, "y": 0.05, "yaw": 0.2}})
    assert plan["success"] and plan["object"]["name"] == "mug" and plan["object"]["kind"] == "mesh"
    assert plan["object"]["mass"] == 0.30
    r = api.post("/v1/plans", json={"hand": "parallel_gripper", "object": {"kind": "builtin", "name": "teapot"},
                                    "strategy": "S", "store": False}, headers=AUTH)  # fmt: skip
    assert "mustard_bottle" in str(assert_problem(r, 422, "object.name"))


def test_one_route_takes_json_and_files_and_refuses_other_media(api: TestClient) -> None:
    ply = MESH_MM.export(file_type="ply")
    as_cloud = api.post("/v1/objects", files={"file": ("box.ply", ply)},
                        data={"mass": "0.15", "scale": "0.001", "kind": "points"}, headers=AUTH)  # fmt: skip
    assert as_cloud.status_code == 201, as_cloud.text
    assert as_cloud.json()["source"] == "ply" and as_cloud.json()["object"]["kind"] == "mesh"  # the cloud's solid
    assert abs(as_cloud.json()["extent_major"] - 0.16) < 1e-6
    cloud = trimesh.PointCloud(np.random.default_rng(0).uniform(0.0, 0.05, (50, 3))).export(file_type="ply")
    before = api.get("/v1/objects").json()["total"]
    refusals = [
        (api.post("/v1/objects", files={"file": ("c.ply", cloud)}, data={"mass": "0.1", "kind": "mesh"},
                  headers=AUTH), 422, "file"),
        (api.post("/v1/objects", files={"file": ("c.ply", cloud)}, data={"mass": "0.1", "colour": "red"},
                  headers=AUTH), 422, "colour"),
        (api.post("/v1/objects", files={"file": ("c.ply", cloud)}, data={"mass": "nan"}, headers=AUTH), 422, "mass"),
        (api.post("/v1/objects", files={"other": ("c.ply", cloud)}, data={"mass": "0.1"}, headers=AUTH), 422, "file"),
        (api.post("/v1/objects", content=b'{"object": {}}', headers={**AUTH, "Content-Type": "text/plain"}), 415,
         "Content-Type"),
        (api.post("/v1/objects", content=b'{"object": ', headers={**AUTH, "Content-Type": "application/json"}), 400,
         "$"),
        (api.post("/v1/objects", json={"object": {"kind": "box", "size": [0.1, 0.1, -1.0], "mass": 0.1}},
                  headers=AUTH), 422, "object.size[2]"),
    ]  # fmt: skip
    for response, status, field in refusals:
        assert_problem(response, status, field)
    assert api.get("/v1/objects").json()["total"] == before


def test_a_json_body_has_the_body_limit_and_a_file_the_upload_limit(tmp_path: Any) -> None:
    from api_helpers import make_settings

    from softsig_service.api.app import create_app

    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.04)  # 642 vertices: about 40 kB as JSON or PLY text
    spec = {"kind": "mesh", "vertices": mesh.vertices.tolist(), "faces": mesh.faces.tolist(), "mass": 0.1}
    with TestClient(create_app(make_settings(tmp_path, max_body_bytes=20_000, max_upload_bytes=200_000))) as small:
        assert_problem(small.post("/v1/objects", json={"object": spec}, headers=AUTH), 413)
        ply = mesh.export(file_type="ply", encoding="ascii")
        assert len(ply) > 20_000
        r = small.post("/v1/objects", files={"file": ("ball.ply", ply)}, data={"mass": "0.1"}, headers=AUTH)
        assert r.status_code == 201, r.text
