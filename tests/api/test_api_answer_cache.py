"""Answers kept per process are never stale: two apps on one registry (as two processes of ``softsig serve``); one
reads a hand and a plan, the other changes or deletes them, and the first answers what the registry holds now."""

from __future__ import annotations

from pathlib import Path

from api_helpers import AUTH, gripper_files, make_settings, upload
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app
from softsig_service.api.plan_schemas import PlanOut
from softsig_service.api.responses import model_json
from softsig_service.api.routes.hands import hand_out
from softsig_service.api.schemas import HandOut
from softsig_service.registry import Registry, get_hand


def test_a_change_made_by_another_process_is_answered_at_once(tmp_path: Path) -> None:
    settings = make_settings(tmp_path)
    with (
        TestClient(create_app(settings)) as reader,
        TestClient(create_app(settings)) as writer,
    ):
        assert writer.post("/v1/hands", files=upload(gripper_files("g")), headers=AUTH).status_code == 201
        first = reader.get("/v1/hands/g")
        assert first.status_code == 200 and reader.get("/v1/hands/g").content == first.content  # kept
        etag = first.headers["etag"]
        assert reader.get("/v1/hands/g", headers={"If-None-Match": etag}).status_code == 304

        put = writer.put("/v1/hands/g", files=upload(gripper_files("g")), headers={**AUTH, "If-Match": etag})
        assert put.status_code == 200
        second = reader.get("/v1/hands/g")
        assert second.headers["etag"] == put.headers["etag"] != etag
        assert second.json()["revision"] == first.json()["revision"] + 1
        assert reader.get("/v1/hands/g", headers={"If-None-Match": etag}).status_code == 200

        # the same bytes FastAPI would send for the record as the registry holds it now
        registry = Registry(settings.resolved_database_url())
        try:
            assert second.content == model_json(HandOut, hand_out(get_hand(registry, "g")))
        finally:
            registry.dispose()

        body = {
            "hand": "g",
            "object": {"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.0, "yaw": 0.0}},
            "strategy": "C",
        }
        plan = writer.post("/v1/plans", json=body, headers=AUTH)
        assert plan.status_code == 201
        path = plan.headers["location"]
        got = reader.get(path)
        assert got.status_code == 200 and got.json() == plan.json()
        assert got.content == model_json(PlanOut, plan.json())
        assert writer.delete(path, headers=AUTH).status_code == 204
        gone = reader.get(path)
        assert gone.status_code == 404 and gone.json()["field"] == "plan_id"

        current = second.headers["etag"]
        assert writer.delete("/v1/hands/g", headers={**AUTH, "If-Match": current}).status_code == 204
        missing = reader.get("/v1/hands/g")
        assert missing.status_code == 404 and missing.json()["field"] == "hand"
