"""Strategy R's capture model is chosen by the hand's revision and the object's shape digest, in one indexed
query; a stale model is refused naming ``capture_version``; with none stored, the model shipped in the hand's
folder is used, as the CLI uses it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from api_helpers import AUTH, REPO_HANDS_DIR, assert_problem, gripper_files, make_settings, upload
from fastapi.testclient import TestClient

from softsig_service import registry as repo
from softsig_service.api.app import create_app
from softsig_service.objects import object_from_json

BOX = {"kind": "builtin", "name": "box"}
SHIPPED = REPO_HANDS_DIR / "pisa_iit_softhand" / "capture" / "box.json"


def _store_capture(ctx: Any, hand: str, obj: dict[str, Any]) -> int:
    """Store a capture model (the shipped SoftHand box model's values: a valid model) of ``obj`` for ``hand``."""
    rec = repo.add_signature(
        ctx.registry, hand, kind="capture", method="box", source="simulation",
        data=json.loads(SHIPPED.read_text(encoding="utf-8")), params={"object": obj},
        object_digest=object_from_json(obj).shape_digest,
    )  # fmt: skip
    return rec.version


def test_a_capture_model_of_an_older_revision_is_refused(tmp_path: Path) -> None:
    plan = {"hand": "g", "object": BOX, "strategy": "R", "sigma_r": 0.1, "sigma_t": 0.01, "store": False}
    with TestClient(create_app(make_settings(tmp_path))) as api:
        ctx = api.app.state.ctx  # type: ignore[attr-defined]
        r = api.post("/v1/hands", files=upload(gripper_files("g", with_mesh=False)), headers=AUTH)
        assert r.status_code == 201, r.text
        version = _store_capture(ctx, "g", BOX)
        assert api.post("/v1/plans", json=plan, headers=AUTH).status_code == 200
        assert api.post("/v1/plans", json={**plan, "capture_version": version}, headers=AUTH).status_code == 200
        files = gripper_files("g", with_mesh=False)
        files["parallel_gripper.xml"] += b"\n<!-- revision 2 -->\n"
        put = api.put("/v1/hands/g", files=upload(files), headers={**AUTH, "If-Match": r.headers["etag"]})
        assert put.status_code == 200, put.text
        stale = assert_problem(api.post("/v1/plans", json=plan, headers=AUTH), 422, "capture_version")
        assert "revisions [1]" in stale["detail"] and "current revision 2" in stale["detail"], stale
        named = {**plan, "capture_version": version}
        assert (
            "revision 1"
            in assert_problem(api.post("/v1/plans", json=named, headers=AUTH), 422, "capture_version")["detail"]
        )
        _store_capture(ctx, "g", BOX)  # computed again on revision 2: planned with
        assert api.post("/v1/plans", json=plan, headers=AUTH).status_code == 200


def test_the_match_is_found_past_a_thousand_other_models(tmp_path: Path) -> None:
    """The lookup is a query by digest, not a scan of the newest thousand records."""
    plan = {"hand": "g", "object": BOX, "strategy": "R", "store": False}
    with TestClient(create_app(make_settings(tmp_path))) as api:
        ctx = api.app.state.ctx  # type: ignore[attr-defined]
        assert api.post("/v1/hands", files=upload(gripper_files("g", with_mesh=False)), headers=AUTH).status_code == 201
        _store_capture(ctx, "g", BOX)  # the oldest
        other = {"kind": "box", "size": [0.1, 0.05, 0.05], "mass": 0.2}
        for _ in range(1000):
            _store_capture(ctx, "g", other)
        out = api.post("/v1/plans", json=plan, headers=AUTH)
        assert out.status_code == 200, out.text


def test_r_over_rest_uses_the_shipped_model_as_the_cli_does(tmp_path: Path) -> None:
    from softsig_service.cli.options import read_capture
    from softsig_service.planning.planner import Planner
    from softsig_service.planning.request import PlanRequest

    body = {"hand": "pisa_iit_softhand", "object": BOX, "strategy": "R", "sigma_r": 0.1, "sigma_t": 0.01}
    with TestClient(create_app(make_settings(tmp_path))) as api:
        out = api.post("/v1/plans", json={**body, "store": False}, headers=AUTH)
    assert out.status_code == 200, out.text
    served = out.json()
    obj = object_from_json(BOX)
    model = read_capture(None, hand="pisa_iit_softhand", obj=obj, strategy="R")
    assert model is not None
    cli = Planner().plan(
        PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="R", sigma_r=0.1, sigma_t=0.01, capture=model)
    )
    assert served["success"] == cli.success
    assert abs(served["quality"]["expected_capture"] - cli.quality["expected_capture"]) < 1e-9
    p = cli.grasp_pose[:3, 3]
    assert all(abs(served["grasp_pose"]["position"][c] - p[i]) < 1e-6 for i, c in enumerate("xyz"))


def test_models_stored_before_the_digest_get_it_at_the_next_start(tmp_path: Path) -> None:
    plan = {"hand": "g", "object": BOX, "strategy": "R", "store": False}
    settings = make_settings(tmp_path)
    with TestClient(create_app(settings)) as api:
        ctx = api.app.state.ctx  # type: ignore[attr-defined]
        assert api.post("/v1/hands", files=upload(gripper_files("g", with_mesh=False)), headers=AUTH).status_code == 201
        repo.add_signature(  # as a registry of the previous schema holds it: no digest
            ctx.registry, "g", kind="capture", method="box", source="simulation",
            data=json.loads(SHIPPED.read_text(encoding="utf-8")), params={"object": BOX},
        )  # fmt: skip
        assert_problem(api.post("/v1/plans", json=plan, headers=AUTH), 422, "capture_version")
    with TestClient(create_app(settings)) as api:
        assert api.post("/v1/plans", json=plan, headers=AUTH).status_code == 200
