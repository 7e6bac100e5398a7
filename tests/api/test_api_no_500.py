"""Inputs that once produced a 500 now get a 4xx problem naming the field (real app, real worker processes)."""

from __future__ import annotations

import json

import pytest
from api_helpers import AUTH, assert_problem, gripper_files, upload
from fastapi.testclient import TestClient

from softsig_service.signatures.markers import parse_markers_csv

MARKERS = "/v1/hands/parallel_gripper/signatures/markers"


def _upload_with_assets(api: TestClient, assets: dict[str, bytes]) -> dict[str, object]:
    files = gripper_files("no500_hand", with_mesh=False)
    files.update(assets)
    response = api.post("/v1/hands", files=upload(files), headers=AUTH)
    assert 400 <= response.status_code < 500, response.text
    body = assert_problem(response, response.status_code)
    assert str(body.get("field", "")).startswith("assets"), body
    assert api.get("/v1/hands/no500_hand").status_code == 404
    return body


def test_asset_file_name_too_long(api: TestClient) -> None:
    _upload_with_assets(api, {"m" * 300 + ".stl": b"solid x\nendsolid x\n"})


def test_asset_that_is_also_a_folder(api: TestClient) -> None:
    _upload_with_assets(api, {"a": b"data", "a/b.stl": b"solid x\nendsolid x\n"})
    _upload_with_assets(api, {"a/b.stl": b"solid x\nendsolid x\n", "a": b"data"})


def test_asset_path_two_thousand_folders_deep(api: TestClient) -> None:
    _upload_with_assets(api, {"d/" * 2000 + "b.stl": b"solid x\nendsolid x\n"})


def test_markers_csv_with_a_huge_cell(api: TestClient) -> None:
    csv = b"time,point,x,y,z\n0," + b"p" * 200_000 + b",0,0,0\n"
    response = api.post(MARKERS, files={"file": ("m.csv", csv)}, headers=AUTH)
    body = assert_problem(response, 422)
    assert "row 2" in body["field"], body


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("[" * 100_000 + "]" * 100_000, "$"),
        (
            json.dumps({"hand": "h", "times": [0.0], "point_names": ["a", "b", "c", "d"]})[:-1]
            + ', "positions": '
            + "[" * 5000
            + "]" * 5000
            + "}",
            "positions",
        ),
    ],
)
def test_markers_json_nested_deep(api: TestClient, text: str, field: str) -> None:
    response = api.post(MARKERS, files={"file": ("m.json", text.encode())}, headers=AUTH)
    body = assert_problem(response, 422)
    assert str(body["field"]).startswith(field), body


def test_lone_surrogate_echoed_in_a_problem(api: TestClient) -> None:
    payload = '{"hand": "\\udc80", "object": {}}'
    response = api.post("/v1/plans", content=payload, headers={**AUTH, "Content-Type": "application/json"})
    body = assert_problem(response, 422)
    assert "\udc80" in json.dumps(body) or "\\udc80" in response.text
    # a path parameter too
    response = api.get("/v1/hands/%ED%B2%80")
    assert 400 <= response.status_code < 500


def test_csv_rows_and_points_are_capped() -> None:
    from softsig_service.errors import InvalidTrajectory

    rows = "".join(f"{k},p{j},0,0,0\n" for k in range(30_000) for j in range(4))
    with pytest.raises(InvalidTrajectory) as info:
        parse_markers_csv("time,point,x,y,z\n" + rows)
    assert info.value.field == "rows"
    many = "".join(f"0,p{j},0,0,0\n" for j in range(300))
    with pytest.raises(InvalidTrajectory) as info:
        parse_markers_csv("time,point,x,y,z\n" + many)
    assert info.value.field == "row 258: point"
