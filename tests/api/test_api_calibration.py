"""Real outcomes and calibration over REST: upload, versions, 422s naming the field, a calibration job whose
variant is registered as a hand."""

from __future__ import annotations

from typing import Any

from api_helpers import AUTH, assert_problem, wait_for
from fastapi.testclient import TestClient

CELL = {"object": "box", "strategy": "C", "trials": 20, "successes": 20}


def finished(client: TestClient, job_id: str) -> dict[str, Any] | None:
    job: dict[str, Any] = client.get(f"/v1/jobs/{job_id}").json()
    return job if job["status"] not in ("queued", "running") else None


def test_outcomes_are_versions_of_the_hand_and_bad_ones_name_the_field(api: TestClient) -> None:
    url = "/v1/hands/pisa_iit_softhand/outcomes"
    for body, field in (
        ({"cells": [{**CELL, "successes": 21}]}, "cells[0].successes"),
        ({"cells": [{**CELL, "object": "anvil"}]}, "cells[0].object"),
        ({"cells": [{**CELL, "strategy": "Q"}]}, "cells[0].strategy"),
        (
            {"trials": [{"object": "box", "strategy": "S", "success": True, "offset": {"dx": 3.0}}]},
            "trials[0].offset.dx",
        ),
    ):
        assert_problem(api.post(url, json=body, headers=AUTH), 422, field)
    assert_problem(api.post(url, json={"cells": [CELL]}), 401, "X-API-Key")
    trials = [{"object": "cylinder", "strategy": "C", "success": ok} for ok in (True, True, False)]
    r = api.post(url, json={"cells": [CELL], "trials": trials, "note": "lab A"}, headers=AUTH)
    assert r.status_code == 201, r.text
    got = r.json()
    assert got["kind"] == "outcomes" and got["source"] == "real"
    assert got["params"] == {"cells": 2, "trials": 23, "successes": 22, "note": "lab A"}
    listed = api.get("/v1/hands/pisa_iit_softhand/signatures", params={"kind": "outcomes"}).json()["items"]
    assert [v["version"] for v in listed] == [got["version"]]
    again = api.get(f"/v1/hands/pisa_iit_softhand/signatures/{got['version']}").json()
    assert again["signature"]["cells"][0]["successes"] == 20


def test_a_calibration_job_registers_its_variant(api: TestClient) -> None:
    outcomes = {"cells": [CELL, {**CELL, "object": "cylinder", "successes": 19}]}
    r = api.post("/v1/hands/pisa_iit_softhand/outcomes", json=outcomes, headers=AUTH)
    assert r.status_code == 201, r.text
    version = r.json()["version"]
    ok = {
        "hand": "pisa_iit_softhand",
        "outcomes_version": version,
        "held_out": [{"object": "cylinder"}],
        "parameters": ["thumb_rest"],
        "budget": 2,
        "test_trials": 1,
        "name": "softhand_lab_a",
    }
    for change, field in (
        ({"parameters": ["palm_width"]}, "parameters[0]"),
        ({"ranges": {"thumb_rest": [0.0, 2.0]}}, "ranges.thumb_rest"),
        ({"budget": 1}, "budget"),
        ({"held_out": [{}]}, "held_out"),
        ({"outcomes_version": 999}, "outcomes_version"),
        ({"hand": "parallel_gripper", "outcomes_version": None}, "outcomes_version"),
        ({"name": "Bad Name"}, "name"),
    ):
        assert_problem(api.post("/v1/calibrations", json={**ok, **change}, headers=AUTH), 422, field)
    r = api.post("/v1/calibrations", json=ok, headers=AUTH)
    assert r.status_code == 202, r.text
    assert "outcomes" not in r.json()["params"] and "hand_ref" not in r.json()["params"]
    job = wait_for(lambda: finished(api, r.json()["id"]), timeout=300)
    assert job["status"] == "succeeded", job
    result = job["result"]
    assert result["variant"] == {"hand": "softhand_lab_a", "links": {"hand": "/v1/hands/softhand_lab_a"}}
    assert set(result["heldout_loglik"]) == {"calibrated", "uncalibrated", "constant_rate"}
    assert result["simulations"] == 2 + 2 and result["outcomes_version"] == version
    names = {f["name"] for f in api.get(f"/v1/jobs/{job['id']}/files").json()["items"]}
    assert {"calibration.json", "report.md", "calibration.png", "evaluations.jsonl"} <= names
    hand = api.get("/v1/hands/softhand_lab_a")
    assert hand.status_code == 200, hand.text
    # the variant is a hand like any other: it plans
    plan = api.post(
        "/v1/plans",
        json={"hand": "softhand_lab_a", "object": {"kind": "builtin", "name": "box"}, "strategy": "C", "store": False},
        headers=AUTH,
    )
    assert plan.status_code == 200, plan.text
    assert_problem(api.post("/v1/calibrations", json=ok, headers=AUTH), 409, "name")
