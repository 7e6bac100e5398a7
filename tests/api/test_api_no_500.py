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


BOX = {"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15}


def test_a_capture_version_past_the_databases_integers(api: TestClient) -> None:
    body = {"hand": "parallel_gripper", "object": BOX, "strategy": "R", "capture_version": 2**63}
    problem = assert_problem(api.post("/v1/plans", json=body, headers=AUTH), 422)
    assert "capture_version" in str(problem.get("field", "")) or "capture_version" in json.dumps(problem), problem


@pytest.mark.parametrize("step", [5e-324, 1.1e-30, 1e-9, 5e-5])
def test_capture_steps_too_fine(api: TestClient, step: float) -> None:
    """Refused by the schema's bound, before any grid is built (1e-9 once allocated 1.5 GB before its 422)."""
    body = {"object": BOX, "step": step}
    problem = assert_problem(api.post("/v1/hands/parallel_gripper/signatures/capture", json=body, headers=AUTH), 422)
    assert "step" in json.dumps(problem), problem


def test_a_capture_grid_is_counted_not_built() -> None:
    """The count of a grid that asks for 10**14 simulations is arithmetic: no array of that size is made."""
    import tracemalloc

    from softsig_service.experiments.capture import CaptureGrid

    grid = CaptureGrid(n_theta=72, half_width=0.1, step=1e-4, holdout=0)
    tracemalloc.start()
    n = grid.simulations
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert n == 72 * 2001**2
    assert peak < 4096, peak  # the 2001 offsets alone would take 16 kB
    assert CaptureGrid(n_theta=12, half_width=0.03, step=0.01).simulations == 12 * 7**2 + 60


def test_a_stiffness_job_on_an_object_too_small_is_refused_at_submission(api: TestClient) -> None:
    tiny = {"kind": "box", "size": [1e-4, 1e-4, 1e-4], "mass": 0.01}
    r = api.post("/v1/hands/parallel_gripper/signatures/stiffness", json={"object": tiny}, headers=AUTH)
    problem = assert_problem(r, 422)
    assert problem["field"] == "object", problem
    assert api.get("/v1/jobs").json()["total"] == 0, "no job was queued"
