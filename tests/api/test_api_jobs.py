"""The job machinery through the app: progress, results and files, cancel, wall-time cap, failures, caps."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from api_helpers import AUTH, TEST_JOB_KINDS, assert_problem, make_settings, pid_alive, wait_for
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app


def submit(client: TestClient, kind: str, params: dict[str, Any], time_limit: float | None = None) -> str:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    record = client.portal.call(lambda: ctx.jobs.submit(kind, params, time_limit))  # type: ignore[union-attr]
    return str(record.id)


def finished(client: TestClient, job_id: str) -> dict[str, Any] | None:
    job: dict[str, Any] = client.get(f"/v1/jobs/{job_id}").json()
    return job if job["status"] not in ("queued", "running") else None


def test_a_job_reports_progress_and_leaves_result_files(api: TestClient) -> None:
    job_id = submit(api, "count", {"n": 8, "dt": 0.01, "gate": True})
    # the job stops half-way until the gate file exists, so its progress is seen whatever the machine's speed
    seen = wait_for(
        lambda: (j := api.get(f"/v1/jobs/{job_id}").json())["status"] == "running" and j["progress"] > 0 and j
    )
    assert 0 < seen["progress"] <= 5 / 8 and seen["message"].startswith("step")
    (api.app.state.ctx.jobs.out_dir(job_id) / "gate").touch()  # type: ignore[attr-defined]
    job = wait_for(lambda: finished(api, job_id))
    assert job["status"] == "succeeded" and job["progress"] == 1.0 and job["result"] == {"n": 8, "total": 36}
    assert job["started_at"] and job["finished_at"] and job["links"]["files"] == f"/v1/jobs/{job_id}/files"
    files = {f["name"]: f for f in api.get(f"/v1/jobs/{job_id}/files").json()["items"]}
    assert set(files) == {"report.md", "data.csv", "sub/result.json", "gate"}
    assert files["data.csv"]["media_type"] == "text/csv" and files["report.md"]["media_type"] == "text/markdown"
    csv = api.get(files["data.csv"]["url"])
    assert (
        csv.status_code == 200
        and csv.text.startswith("i,value\n")
        and csv.headers["content-type"].startswith("text/csv")
    )
    assert api.get(f"/v1/jobs/{job_id}/files/sub/result.json").json() == {"n": 8}
    for escape in ("../../registry.sqlite3", "%2e%2e/%2e%2e/registry.sqlite3", "sub/../../../registry.sqlite3"):
        r = api.get(f"/v1/jobs/{job_id}/files/{escape}")
        assert 400 <= r.status_code < 500 and b"SQLite" not in r.content
        assert_problem(r, r.status_code)
    assert_problem(api.get(f"/v1/jobs/{job_id}/files/nothing.csv"), 404, "name")
    assert_problem(api.post(f"/v1/jobs/{job_id}/cancel", headers=AUTH), 409, "job_id")
    assert job_id in {j["id"] for j in api.get("/v1/jobs", params={"status": "succeeded"}).json()["items"]}


def test_cancel_kills_the_job_and_its_workers(api: TestClient) -> None:
    job_id = submit(api, "sleep_forever", {})
    out = api.app.state.ctx.jobs.out_dir(job_id)  # type: ignore[attr-defined]
    pids = wait_for(lambda: (out / "pids.json").is_file() and json.loads((out / "pids.json").read_text()))
    assert pid_alive(pids["job"]) and pid_alive(pids["helper"])
    assert_problem(api.post(f"/v1/jobs/{job_id}/cancel"), 401)
    r = api.post(f"/v1/jobs/{job_id}/cancel", headers=AUTH)
    assert r.status_code == 202 and r.json()["cancel_requested"] is True
    job = wait_for(lambda: finished(api, job_id))
    assert job["status"] == "cancelled"
    wait_for(lambda: not pid_alive(pids["job"]) and not pid_alive(pids["helper"]), timeout=60)


def test_wall_time_cap_failures_and_crashes(api: TestClient) -> None:
    capped = submit(api, "sleep_forever", {}, time_limit=1.5)
    failing = submit(api, "fail", {"trials": 99})
    crashing = submit(api, "crash", {})
    job = wait_for(lambda: finished(api, capped), timeout=180)
    assert job["status"] == "timed_out" and job["time_limit"] == 1.5 and job["error"]["field"] == "time_limit"
    job = wait_for(lambda: finished(api, failing), timeout=180)
    assert job["status"] == "failed" and job["error"]["field"] == "trials" and job["error"]["value"] == 99
    assert job["error"]["type"] == "urn:softsig:problem:invalid-input" and job["error"]["choices"] == ["1", "2"]
    job = wait_for(lambda: finished(api, crashing), timeout=180)
    assert job["status"] == "failed" and "exited" in job["message"]


def test_a_job_may_start_worker_processes(api: TestClient) -> None:
    job_id = submit(api, "spawn_workers", {})
    job = wait_for(lambda: finished(api, job_id), timeout=180)
    assert job["status"] == "succeeded", job
    assert job["result"] == {"values": [1, 2, 3]}


def test_queue_cap_and_a_restart_resumes_unfinished_jobs(tmp_path: Path, database_url: str) -> None:
    settings = make_settings(tmp_path, max_queued_jobs=2, job_workers=1, database_url=database_url)
    with TestClient(create_app(settings, job_kinds=TEST_JOB_KINDS)) as client:
        first = submit(client, "sleep_forever", {})
        second = submit(client, "sleep_forever", {})
        wait_for(lambda: client.get(f"/v1/jobs/{first}").json()["status"] == "running")
        assert client.get(f"/v1/jobs/{second}").json()["status"] == "queued", "one job runs at a time"
        try:
            submit(client, "count", {})
        except Exception as exc:  # ServiceBusy raised inside the portal
            assert type(exc).__name__ == "ServiceBusy"
        else:
            raise AssertionError("a third job must be refused")
        r = client.post(f"/v1/jobs/{second}/cancel", headers=AUTH)
        assert r.status_code == 202
        assert wait_for(lambda: finished(client, second))["status"] == "cancelled"
        assert client.get(f"/v1/jobs/{first}").json()["attempts"] == 1
    # the service stopped with the first job running: it handed the job back, and the next start resumes it
    with TestClient(create_app(settings, job_kinds=TEST_JOB_KINDS)) as client:
        job = wait_for(lambda: (j := client.get(f"/v1/jobs/{first}").json())["status"] == "running" and j)
        assert job["attempts"] == 2 and job["message"].startswith("resumed")
        assert client.post(f"/v1/jobs/{first}/cancel", headers=AUTH).status_code == 202
        assert wait_for(lambda: finished(client, first))["status"] == "cancelled"


def test_unknown_jobs(api: TestClient) -> None:
    assert_problem(api.get("/v1/jobs/" + "a" * 32), 404, "job_id")
    assert_problem(api.get("/v1/jobs/xyz"), 422, "job_id")
    assert_problem(api.post("/v1/jobs/" + "a" * 32 + "/cancel", headers=AUTH), 404, "job_id")


def test_a_starved_event_loop_keeps_its_jobs_lease(tmp_path: Path, database_url: str) -> None:
    """The event loop held for three leases (a burst of requests, a slow hook, a starved CPU): the lease of the
    running job is renewed all the same, so another process cannot claim it and redo it."""
    import time

    from softsig_service import registry as repo

    lease = 1.0
    settings = make_settings(tmp_path, job_workers=1, job_lease=lease, job_poll_interval=0.2, database_url=database_url)
    with TestClient(create_app(settings, job_kinds=TEST_JOB_KINDS)) as client:
        job_id = submit(client, "count", {"n": 4, "gate": True})
        wait_for(lambda: client.get(f"/v1/jobs/{job_id}").json()["progress"] > 0)
        ctx = client.app.state.ctx  # type: ignore[attr-defined]

        async def hog() -> repo.Claim | None:  # holds the event loop (pure Python, as a CPU-bound handler does)
            end = time.monotonic() + 3 * lease
            while time.monotonic() < end:
                pass
            # another process tries its claim while this one's loop is still held
            return repo.claim_job(ctx.registry, "another-process", lease, kinds=("count",), max_attempts=3)

        other = client.portal.call(hog)
        assert other is None, "the job's lease expired while its holder was alive"
        (ctx.jobs.out_dir(job_id) / "gate").touch()
        job = wait_for(lambda: finished(client, job_id))
        assert job["status"] == "succeeded" and job["attempts"] == 1, job
