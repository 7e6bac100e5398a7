"""Registry hygiene: DELETE of a stored plan, retention of plans and job files, and a process serving a hand
that another process replaced or deleted (two apps on one registry and data folder)."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest
from api_helpers import AUTH, TEST_JOB_KINDS, assert_problem, gripper_files, make_settings, upload, wait_for
from fastapi.testclient import TestClient
from sqlalchemy import update

from softsig_service.api.app import create_app
from softsig_service.registry.models import JobRow, PlanRow, utcnow

PLAN = {"hand": "parallel_gripper", "object": {"kind": "builtin", "name": "box"}, "strategy": "S"}


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("hygiene")


@pytest.fixture(scope="module")
def api(data: Path) -> Iterator[TestClient]:
    with TestClient(create_app(make_settings(data), job_kinds=TEST_JOB_KINDS)) as client:
        yield client


def test_delete_a_stored_plan(api: TestClient, data: Path) -> None:
    plan = api.post("/v1/plans", json=PLAN, headers=AUTH).json()
    assert api.get(f"/v1/plans/{plan['id']}/image.png").status_code == 200
    image = data / "plans" / f"{plan['id']}.png"
    assert image.is_file()
    assert_problem(api.delete(f"/v1/plans/{plan['id']}"), 401, "X-API-Key")
    assert api.delete(f"/v1/plans/{plan['id']}", headers=AUTH).status_code == 204
    assert_problem(api.get(f"/v1/plans/{plan['id']}"), 404, "plan_id")
    assert not image.exists()
    assert_problem(api.delete(f"/v1/plans/{plan['id']}", headers=AUTH), 404, "plan_id")


def _age(client: TestClient, table: type[PlanRow] | type[JobRow], ident: str, days: float) -> None:
    registry = client.app.state.ctx.registry  # type: ignore[attr-defined]
    then = utcnow() - timedelta(days=days)
    with registry.write() as s:
        values = {"created_at": then, "finished_at": then} if table is JobRow else {"created_at": then}
        s.execute(update(table).where(table.id == ident).values(**values))


def test_retention_removes_old_plans_and_job_files(api: TestClient, data: Path) -> None:
    old_plan = api.post("/v1/plans", json=PLAN, headers=AUTH).json()["id"]
    api.get(f"/v1/plans/{old_plan}/image.png")
    new_plan = api.post("/v1/plans", json=PLAN, headers=AUTH).json()["id"]
    job = api.post("/v1/validations", json={**PLAN, "trials": 1}, headers=AUTH).json()["id"]
    wait_for(lambda: api.get(f"/v1/jobs/{job}").json()["status"] not in ("queued", "running"), timeout=300)
    assert (data / "jobs" / job).is_dir()
    _age(api, PlanRow, old_plan, 30)
    _age(api, JobRow, job, 30)
    settings = make_settings(data, retention_days=7.0, retention_interval=3600.0)
    with TestClient(create_app(settings, job_kinds=TEST_JOB_KINDS)) as other:  # purges at startup
        assert_problem(other.get(f"/v1/plans/{old_plan}"), 404)
        assert other.get(f"/v1/plans/{new_plan}").status_code == 200
        assert_problem(other.get(f"/v1/jobs/{job}"), 404)
    assert not (data / "plans" / f"{old_plan}.png").exists()
    assert not (data / "jobs" / job).exists()


def test_a_hand_changed_or_deleted_by_another_process(api: TestClient, data: Path) -> None:
    files = gripper_files("shared_gripper")
    created = api.post("/v1/hands", files=upload(files), headers=AUTH)
    assert created.status_code == 201, created.text
    url = "/v1/hands/shared_gripper/signatures/closure"
    assert api.post(url, json={}, headers=AUTH).status_code == 201  # this process has served the hand
    with TestClient(create_app(make_settings(data), job_kinds=TEST_JOB_KINDS)) as other:
        etag = other.get("/v1/hands/shared_gripper").json()["etag"]
        put = other.put("/v1/hands/shared_gripper", files=upload(files), headers={**AUTH, "If-Match": etag})
        assert put.status_code == 200, put.text
        again = api.post(url, json={}, headers=AUTH)  # the first revision's folder is gone
        assert again.status_code == 201, again.text
        assert again.json()["hand_revision"] == 2
        gone = other.delete("/v1/hands/shared_gripper", headers={**AUTH, "If-Match": put.json()["etag"]})
        assert gone.status_code == 204
    assert_problem(api.post(url, json={}, headers=AUTH), 404, "hand")
