"""Idempotency-Key on creating POSTs: a retry replays the first response, creates nothing, survives a restart."""

from __future__ import annotations

from pathlib import Path

from api_helpers import AUTH, KEY, assert_problem, make_settings
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app
from softsig_service.registry.db import Registry
from softsig_service.registry.idempotency import (
    claim_key,
    complete_key,
    find_key,
    purge_expired_keys,
    release_key,
)

BOX = {"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.05, "yaw": 0.4}}
PLAN = {"hand": "sdm_hand", "object": BOX, "strategy": "S"}


def _plans(client: TestClient) -> int:
    return int(client.get("/v1/plans").json()["total"])


def test_a_retried_plan_is_the_first_plan_even_after_a_restart(tmp_path: Path) -> None:
    settings = make_settings(tmp_path)
    with TestClient(create_app(settings)) as api:
        before = _plans(api)
        headers = {**AUTH, "Idempotency-Key": "plan-0001"}
        first = api.post("/v1/plans", json=PLAN, headers=headers)
        assert first.status_code == 201, first.text
        assert "idempotent-replayed" not in first.headers
        again = api.post("/v1/plans", json=PLAN, headers=headers)
        assert again.status_code == 201 and again.headers["idempotent-replayed"] == "true"
        assert again.json() == first.json() and again.headers["location"] == first.headers["location"]
        assert _plans(api) == before + 1, "the retry created nothing"
        # the same key with another body is an error naming the header; another key is another plan
        other = {**PLAN, "strategy": "C"}
        assert_problem(api.post("/v1/plans", json=other, headers=headers), 422, "Idempotency-Key")
        assert (
            api.post("/v1/plans", json=PLAN, headers={**AUTH, "Idempotency-Key": "plan-0002"}).json()["id"]
            != (first.json()["id"])
        )
        # without the header nothing changes
        assert api.post("/v1/plans", json=PLAN, headers=AUTH).json()["id"] != first.json()["id"]
        count = _plans(api)
    with TestClient(create_app(settings)) as api:  # a new process on the same registry file
        replay = api.post("/v1/plans", json=PLAN, headers=headers)
        assert replay.headers["idempotent-replayed"] == "true" and replay.json()["id"] == first.json()["id"]
        assert _plans(api) == count


def test_a_failed_first_request_is_not_kept_and_bad_keys_are_refused(tmp_path: Path) -> None:
    with TestClient(create_app(make_settings(tmp_path, api_keys=[KEY, "other-key-9876543210"]))) as api:
        headers = {**AUTH, "Idempotency-Key": "k1"}
        assert_problem(api.post("/v1/plans", json={**PLAN, "strategy": "Z"}, headers=headers), 422, "strategy")
        ok = api.post("/v1/plans", json=PLAN, headers=headers)
        assert ok.status_code == 201 and "idempotent-replayed" not in ok.headers, "the failure was not replayed"
        # the key's scope is the caller: another API key with the same key makes its own plan
        mine = api.post("/v1/plans", json=PLAN, headers={"X-API-Key": "other-key-9876543210", "Idempotency-Key": "k1"})
        assert mine.status_code == 201 and mine.json()["id"] != ok.json()["id"]
        assert_problem(api.post("/v1/plans", json=PLAN, headers={**AUTH, "Idempotency-Key": ""}), 400,
                       "Idempotency-Key")  # fmt: skip
        assert_problem(api.post("/v1/plans", json=PLAN, headers={**AUTH, "Idempotency-Key": "x" * 256}), 400,
                       "Idempotency-Key")  # fmt: skip


def test_a_retried_signature_is_the_same_version(tmp_path: Path) -> None:
    with TestClient(create_app(make_settings(tmp_path))) as api:
        headers = {**AUTH, "Idempotency-Key": "cs-1"}
        url = "/v1/hands/parallel_gripper/signatures/closure"
        first = api.post(url, json={"cs_method": "pca"}, headers=headers)
        again = api.post(url, json={"cs_method": "pca"}, headers=headers)
        assert first.status_code == again.status_code == 201
        assert again.json()["version"] == first.json()["version"] and again.headers["etag"] == first.headers["etag"]
        assert api.get("/v1/hands/parallel_gripper/signatures").json()["total"] == 1


def test_a_key_in_progress_is_held_once(tmp_path: Path) -> None:
    reg = Registry(f"sqlite:///{tmp_path / 'r.sqlite3'}")
    try:
        assert claim_key(reg, "s") is True
        assert claim_key(reg, "s") is False, "a second request while the first is served"
        stored = find_key(reg, "s")
        assert stored is not None and stored.status is None
        complete_key(reg, "s", request_hash="h", status=201, headers={"location": "/x"}, body="{}")
        done = find_key(reg, "s")
        assert done is not None and (done.status, done.request_hash, done.headers) == (201, "h", {"location": "/x"})
        assert find_key(reg, "s", ttl=0.0) is None, "expired records are absent"
        assert claim_key(reg, "s", ttl=0.0) is True, "an expired record can be claimed again"
        release_key(reg, "s")
        assert find_key(reg, "s") is None
        claim_key(reg, "t")
        assert purge_expired_keys(reg) == 0, "a fresh record is kept"
        assert purge_expired_keys(reg, ttl=0.0) == 1 and find_key(reg, "t") is None
    finally:
        reg.dispose()
