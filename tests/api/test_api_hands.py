"""/v1/hands through the real app: built-in hands, upload with every check of the hand library, ETags, auth."""

from __future__ import annotations

import re
from pathlib import Path

from api_helpers import AUTH, assert_problem, gripper_files, make_settings, upload
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app

BUILTIN = {"parallel_gripper", "pisa_iit_softhand", "rbo_hand2", "sdm_hand"}


def test_builtin_hands_are_registered_at_first_start(api: TestClient) -> None:
    r = api.get("/v1/hands")
    assert r.status_code == 200
    items = {h["name"]: h for h in r.json()["items"]}
    assert set(items) >= BUILTIN
    pisa = items["pisa_iit_softhand"]
    assert pisa["builtin"] is True and pisa["revision"] == 1 and pisa["reference_points"][-1] == "wrist"
    one = api.get("/v1/hands/pisa_iit_softhand")
    assert one.status_code == 200 and one.headers["etag"] == pisa["etag"]
    info = one.json()["info"]
    assert info["frame_id"] == "hand" and info["mount"] == "mount" and "folder" not in info
    again = api.get("/v1/hands/pisa_iit_softhand", headers={"If-None-Match": pisa["etag"]})
    assert again.status_code == 304


def test_register_get_replace_delete_a_hand(api: TestClient) -> None:
    files = gripper_files("my_gripper")
    r = api.post("/v1/hands", files=upload(files), headers=AUTH)
    assert r.status_code == 201, r.text
    body = r.json()
    assert r.headers["location"] == "/v1/hands/my_gripper" and r.headers["etag"] == body["etag"]
    assert re.fullmatch(r'"my_gripper\.r1\.[0-9a-f]{8}"', body["etag"])
    assert body["builtin"] is False and body["model_format"] == "mjcf"
    assert {f["path"] for f in body["files"]} == {"hand.toml", "parallel_gripper.xml", "scene.xml", "meshes/tet.obj"}
    assert any(g["type"] == "slide" for g in body["info"]["joints"])
    assert "my_gripper" in {h["name"] for h in api.get("/v1/hands").json()["items"]}

    assert_problem(api.post("/v1/hands", files=upload(files), headers=AUTH), 409, "manifest.name")

    # updates need If-Match: 428 without, 412 with a stale ETag
    assert_problem(api.put("/v1/hands/my_gripper", files=upload(files), headers=AUTH), 428, "If-Match")
    stale = {**AUTH, "If-Match": '"my_gripper.r7"'}
    assert_problem(api.put("/v1/hands/my_gripper", files=upload(files), headers=stale), 412, "If-Match")
    put = api.put("/v1/hands/my_gripper", files=upload(files), headers={**AUTH, "If-Match": body["etag"]})
    assert put.status_code == 200, put.text
    assert put.json()["revision"] == 2 and put.headers["etag"] == body["etag"].replace(".r1.", ".r2.")
    renamed = gripper_files("other_name")
    assert_problem(
        api.put("/v1/hands/my_gripper", files=upload(renamed), headers={**AUTH, "If-Match": put.headers["etag"]}),
        422,
        "manifest.name",
    )

    assert_problem(api.delete("/v1/hands/my_gripper", headers=AUTH), 428, "If-Match")
    assert_problem(api.delete("/v1/hands/my_gripper", headers={**AUTH, "If-Match": body["etag"]}), 412, "If-Match")
    gone = api.delete("/v1/hands/my_gripper", headers={**AUTH, "If-Match": put.headers["etag"]})
    assert gone.status_code == 204
    assert_problem(api.get("/v1/hands/my_gripper"), 404, "hand")
    data_dir = api.app.state.ctx.hands_dir  # type: ignore[attr-defined]
    assert not any((data_dir / "my_gripper").glob("*/hand.toml")), "the hand's files are removed"

    # registered again under the same name: a new life, new ETags; the old ones match nothing
    again = api.post("/v1/hands", files=upload(files), headers=AUTH)
    assert again.status_code == 201 and again.json()["revision"] == 1
    assert again.headers["etag"] != body["etag"] and again.headers["etag"].startswith('"my_gripper.r1.')
    assert_problem(api.delete("/v1/hands/my_gripper", headers={**AUTH, "If-Match": body["etag"]}), 412, "If-Match")
    sig = api.post("/v1/hands/my_gripper/signatures/closure", json={"cs_method": "pca"}, headers=AUTH)
    assert sig.status_code == 201 and sig.headers["etag"].startswith('"my_gripper.v1.')
    assert api.delete("/v1/hands/my_gripper", headers={**AUTH, "If-Match": again.headers["etag"]}).status_code == 204
    third = api.post("/v1/hands", files=upload(files), headers=AUTH)
    sig3 = api.post("/v1/hands/my_gripper/signatures/closure", json={"cs_method": "pca"}, headers=AUTH)
    assert sig3.headers["etag"] != sig.headers["etag"], "version 1 of another life of the hand"
    assert api.delete("/v1/hands/my_gripper", headers={**AUTH, "If-Match": third.headers["etag"]}).status_code == 204


def test_builtin_hands_cannot_be_deleted(api: TestClient) -> None:
    etag = api.get("/v1/hands/sdm_hand").headers["etag"]
    assert_problem(api.delete("/v1/hands/sdm_hand", headers={**AUTH, "If-Match": etag}), 409, "hand")


def test_writes_need_a_valid_api_key(api: TestClient) -> None:
    files = gripper_files("keyless")
    assert_problem(api.post("/v1/hands", files=upload(files)), 401, "X-API-Key")
    r = api.post("/v1/hands", files=upload(files), headers={"X-API-Key": "wrong"})
    body = assert_problem(r, 401, "X-API-Key")
    assert "X-API-Key" in r.headers["www-authenticate"] and body["request_id"] == r.headers["x-request-id"]
    assert api.get("/v1/hands/keyless").status_code == 404


def test_upload_checks_of_the_hand_library(api: TestClient) -> None:
    # an asset path that climbs out of the hand's folder
    files = gripper_files("escaper")
    files["../outside.obj"] = files.pop("meshes/tet.obj")
    assert_problem(api.post("/v1/hands", files=upload(files), headers=AUTH), 422, "assets[1]")
    # an absolute asset path
    files = gripper_files("escaper")
    files["/etc/passwd"] = b"x"
    assert_problem(api.post("/v1/hands", files=upload(files), headers=AUTH), 422, "assets[2]")
    # a model whose mesh reference leaves the folder (checked by the hand library when loading)
    files = gripper_files("escaper")
    files["parallel_gripper.xml"] = files["parallel_gripper.xml"].replace(b"meshes/tet.obj", b"../../tet.obj")
    body = assert_problem(api.post("/v1/hands", files=upload(files), headers=AUTH), 422)
    assert body["type"].endswith("unsafe-path") and "model" in body["field"]
    # a referenced mesh that was not uploaded
    files = gripper_files("escaper")
    del files["meshes/tet.obj"]
    body = assert_problem(api.post("/v1/hands", files=upload(files), headers=AUTH), 422)
    assert body["type"].endswith("invalid-hand-model")
    # a manifest field of the wrong kind, named with its path
    files = gripper_files("escaper")
    files["hand.toml"] = files["hand.toml"].replace(b'kind = "posture"', b'kind = "magic"')
    body = assert_problem(api.post("/v1/hands", files=upload(files), headers=AUTH), 422, "manifest.closure.kind")
    assert body["choices"] == ["actuator", "posture", "synergy"]
    # not TOML at all
    files["hand.toml"] = b"name = [unclosed"
    assert_problem(api.post("/v1/hands", files=upload(files), headers=AUTH), 422, "manifest")
    # the model part is not the file the manifest names
    files = gripper_files("escaper")
    parts = [p if p[0] != "model" else ("model", ("robot.urdf", p[1][1])) for p in upload(files)]
    assert_problem(api.post("/v1/hands", files=parts, headers=AUTH), 422, "model")
    # a missing part
    assert_problem(api.post("/v1/hands", files=upload(files)[:1], headers=AUTH), 422, "model")
    assert api.get("/v1/hands/escaper").status_code == 404
    leftovers = list((api.app.state.ctx.hands_dir / "escaper").glob("*"))  # type: ignore[attr-defined]
    assert leftovers == [], "a rejected upload leaves no files"


def test_size_limits_give_413(tmp_path: Path) -> None:
    settings = make_settings(tmp_path, limits={"max_asset_bytes": 600}, max_upload_bytes=50_000)
    with TestClient(create_app(settings)) as client:
        files = gripper_files("big_mesh")
        files["meshes/tet.obj"] = files["meshes/tet.obj"] + b"#" * 700
        body = assert_problem(client.post("/v1/hands", files=upload(files), headers=AUTH), 413, "assets[1]")
        assert body["type"].endswith("model-too-large")
        files["meshes/big.bin"] = b"\0" * 60_000  # the whole request is over max_upload_bytes
        body = assert_problem(client.post("/v1/hands", files=upload(files), headers=AUTH), 413, "body")
        assert body["type"].endswith("content-too-large") and body["limit"] == 50_000


def test_reads_can_require_a_key_and_writes_without_keys_are_refused(tmp_path: Path) -> None:
    with TestClient(create_app(make_settings(tmp_path / "a", read_auth=True))) as client:
        assert_problem(client.get("/v1/hands"), 401, "X-API-Key")
        assert client.get("/v1/hands", headers=AUTH).status_code == 200
        assert client.get("/healthz").status_code == 200
    with TestClient(create_app(make_settings(tmp_path / "b", api_keys=[]))) as client:
        body = assert_problem(client.post("/v1/hands", files=upload(gripper_files()), headers=AUTH), 401)
        assert "no API key" in body["detail"]
        assert client.get("/v1/hands").status_code == 200
