"""Several service processes on one registry (``softsig serve``, real processes on a real SQLite file): they share
the jobs, and a job whose process is killed (``kill -9``) completes in the other process once its lease expires."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from api_helpers import pid_alive, trickle, wait_for

KEY = {"X-API-Key": "k"}
BOX = {"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Service:
    """One ``softsig serve --workers 1`` process."""

    def __init__(self, data_dir: Path, log: Path) -> None:
        self.port = _free_port()
        env = {
            **os.environ,
            "SOFTSIG_DATA_DIR": str(data_dir),
            "SOFTSIG_API_KEYS": "k",
            "SOFTSIG_WARM_PLANNER": "false",
            "SOFTSIG_JOB_LEASE": "2",
            "SOFTSIG_JOB_POLL_INTERVAL": "0.2",
        }
        self.log = log.open("w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "softsig_service.cli", "serve", "--workers", "1", "--port", str(self.port)],
            env=env, stdout=self.log, stderr=subprocess.STDOUT,
        )  # fmt: skip
        self.http = httpx.Client(base_url=f"http://127.0.0.1:{self.port}", timeout=30.0)

    def ready(self) -> bool:
        assert self.proc.poll() is None, "the service exited"
        try:
            return self.http.get("/readyz").status_code == 200
        except httpx.TransportError:
            return False

    def job(self, job_id: str) -> dict[str, Any]:
        body: dict[str, Any] = self.http.get(f"/v1/jobs/{job_id}").json()
        return body

    def validate(self, trials: int) -> str:
        r = self.http.post(
            "/v1/validations", headers=KEY,
            json={"hand": "parallel_gripper", "object": BOX, "strategy": "S", "trials": trials},
        )  # fmt: skip
        assert r.status_code == 202, r.text
        return str(r.json()["id"])

    def stop(self) -> None:
        self.http.close()
        terminate(self.proc)
        self.log.close()


@pytest.fixture()
def services(tmp_path: Path) -> Iterator[tuple[Service, Service]]:
    data = tmp_path / "data"
    pair = (Service(data, tmp_path / "a.log"), Service(data, tmp_path / "b.log"))
    try:
        for s in pair:
            wait_for(s.ready, timeout=180, poll=0.2)
        yield pair
    finally:
        for s in pair:
            s.stop()


def _owner_pid(data: Path, job_id: str) -> int | None:
    with sqlite3.connect(data / "registry.sqlite3") as db:
        row = db.execute("SELECT owner FROM jobs WHERE id = ?", (job_id,)).fetchone()
    return int(row[0].split(":")[1]) if row and row[0] else None


def _done(service: Service, job_id: str) -> dict[str, Any] | None:
    job = service.job(job_id)
    return job if job["status"] not in ("queued", "running") else None


def test_two_processes_share_the_jobs_of_one_registry(services: tuple[Service, Service], tmp_path: Path) -> None:
    a, b = services
    ids = [a.validate(trials=2), a.validate(trials=2)]
    jobs = [wait_for(lambda i=i: _done(b, i), timeout=240) for i in ids]  # b sees what a was given
    assert [j["status"] for j in jobs] == ["succeeded", "succeeded"], jobs
    assert all(j["attempts"] == 1 for j in jobs), "neither failed or redid the other's job"
    owners = {_owner_pid(tmp_path / "data", i) for i in ids}
    assert owners == {a.proc.pid, b.proc.pid}, "each process ran one (a runs one job at a time)"


def test_a_killed_process_leaves_its_job_to_the_other(services: tuple[Service, Service], tmp_path: Path) -> None:
    a, b = services
    # long enough (about 5 s of trials at 14 trials/s here) that a progress report (sent at most every 0.2 s) lands
    # before the job ends, whatever the machine's speed: 8 trials once finished between two reports
    trials = 64
    job_id = a.validate(trials=trials)
    wait_for(lambda: a.job(job_id)["status"] == "running" and a.job(job_id)["progress"] > 0, timeout=240)
    holder = _owner_pid(tmp_path / "data", job_id)
    victim, survivor = (a, b) if holder == a.proc.pid else (b, a)
    assert holder == victim.proc.pid
    victim.proc.send_signal(signal.SIGKILL)
    victim.proc.wait(10)
    job = wait_for(lambda: _done(survivor, job_id), timeout=240)
    assert job["status"] == "succeeded" and job["attempts"] == 2, job
    assert job["result"]["trials"] == trials and len(job["result"]["outcomes"]) == trials
    assert _owner_pid(tmp_path / "data", job_id) == survivor.proc.pid
    files = {f["name"] for f in survivor.http.get(f"/v1/jobs/{job_id}/files").json()["items"]}
    assert {"validation.json", "outcomes.csv"} <= files
    assert not pid_alive(victim.proc.pid)


def _healthz_count(text: str) -> float:
    """``softsig_http_requests_total`` of ``GET /healthz`` with status 200 in a Prometheus text exposition."""
    total = 0.0
    for line in text.splitlines():
        if line.startswith("softsig_http_requests_total{") and 'route="/healthz"' in line and 'status="200"' in line:
            total += float(line.rsplit(" ", 1)[1])
    return total


def test_metrics_of_several_processes_count_together(tmp_path: Path) -> None:
    """``softsig serve --workers 2``: requests spread over new connections land in both processes, and every scrape
    of /metrics, whichever process answers it, counts all of them."""
    metrics_dir = tmp_path / "metrics"
    with serve_workers(tmp_path, metrics_dir) as url:
        before = _healthz_count(httpx.get(f"{url}/metrics", timeout=10).text)
        n = 60
        for _ in range(n):  # a new connection each: the two processes accept them in turn
            assert httpx.get(f"{url}/healthz", timeout=10).status_code == 200
        writers = {p.name.rsplit("_", 1)[-1] for p in metrics_dir.glob("counter_*.db")}
        assert len(writers) >= 2, f"one process served every request: {writers}"
        for _ in range(6):  # each scrape may be answered by either process
            assert _healthz_count(httpx.get(f"{url}/metrics", timeout=10).text) == before + n


@contextlib.contextmanager
def serve_workers(tmp_path: Path, metrics_dir: Path, **settings: str) -> Iterator[str]:
    """``softsig serve --workers 2`` on a free port, its registry in ``tmp_path/data``, its multiprocess metrics
    in ``metrics_dir`` and ``settings`` as ``SOFTSIG_*`` variables; yields its URL once both processes answer,
    stops it after."""
    metrics_dir.mkdir()
    port = _free_port()
    env = {**os.environ, "SOFTSIG_DATA_DIR": str(tmp_path / "data"), "SOFTSIG_API_KEYS": "k",
           "SOFTSIG_WARM_PLANNER": "false", "PROMETHEUS_MULTIPROC_DIR": str(metrics_dir),
           **{f"SOFTSIG_{key.upper()}": value for key, value in settings.items()}}  # fmt: skip
    url = f"http://127.0.0.1:{port}"
    with (tmp_path / "serve.log").open("w") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "softsig_service.cli", "serve", "--workers", "2", "--port", str(port)],
            env=env, stdout=log, stderr=subprocess.STDOUT,
        )  # fmt: skip
        try:

            def both_ready() -> bool:
                assert proc.poll() is None, "the service exited"
                try:
                    return all(httpx.get(f"{url}/readyz", timeout=5).status_code == 200 for _ in range(4))
                except httpx.TransportError:
                    return False

            wait_for(both_ready, timeout=180, poll=0.5)
            yield url
        finally:
            terminate(proc)


def terminate(proc: subprocess.Popen[bytes]) -> None:
    """SIGTERM, then SIGKILL if the process has not ended within 30 s."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)


def _plans_served(metrics_dir: Path) -> dict[str, float]:
    """By process id: how many ``POST /v1/plans`` it answered 200 (its counter file of the multiprocess metrics)."""
    from prometheus_client.mmap_dict import MmapedDict

    out: dict[str, float] = {}
    for path in metrics_dir.glob("counter_*.db"):
        d = MmapedDict(str(path), read_mode=True)
        try:
            for key, value, *_ in d.read_all_values():
                _, name, labels, _help = json.loads(key)
                if (
                    name == "softsig_http_requests_total"
                    and labels.get("route") == "/v1/plans"
                    and (labels.get("status") == "200")
                ):
                    pid = path.stem.rsplit("_", 1)[-1]
                    out[pid] = out.get(pid, 0.0) + value
        finally:
            d.close()
    return out


def test_a_replaced_hand_is_planned_anew_by_every_worker(tmp_path: Path) -> None:
    """``softsig serve --workers 2``: plans of a hand warm both processes' caches; the hand replaced (PUT) through
    one of them, then deleted and re-created, every plan from either process equals a fresh process's (1e-9)."""
    from api_helpers import gripper_files, upload
    from test_api_hand_changes import PLAN, _close, _fresh_plan, _long_jaws

    short, long = gripper_files("g"), _long_jaws(gripper_files("g"))
    expected_long, expected_short = _fresh_plan(tmp_path / "f1", long), _fresh_plan(tmp_path / "f2", short)
    metrics_dir = tmp_path / "metrics"

    def plans(url: str, n: int) -> list[dict[str, Any]]:  # a new connection each: both processes answer some
        out = []
        for _ in range(n):
            r = httpx.post(f"{url}/v1/plans", json=PLAN, headers=KEY, timeout=120)
            assert r.status_code == 200, r.text
            out.append(r.json())
        return out

    with serve_workers(tmp_path, metrics_dir) as url:
        r = httpx.post(f"{url}/v1/hands", files=upload(short), headers=KEY, timeout=60)
        assert r.status_code == 201, r.text
        assert all(_close(p, expected_short) for p in plans(url, 16))
        before = _plans_served(metrics_dir)
        assert len(before) == 2, f"one process planned every request: {before}"
        put = httpx.put(f"{url}/v1/hands/g", files=upload(long), headers={**KEY, "If-Match": r.headers["etag"]},
                        timeout=60)  # fmt: skip
        assert put.status_code == 200, put.text
        # which process accepts a connection is the kernel's choice: plan until both have planned the new hand
        # (at most 96 requests), every answer the fresh process's
        for _ in range(6):
            assert all(p["hand_revision"] == 2 and _close(p, expected_long) for p in plans(url, 16))
            after = _plans_served(metrics_dir)
            if all(after[pid] > before[pid] for pid in before):
                break
        assert all(after[pid] > before[pid] for pid in before), (before, after)
        d = httpx.delete(f"{url}/v1/hands/g", headers={**KEY, "If-Match": put.headers["etag"]}, timeout=60)
        assert d.status_code == 204, d.text
        assert httpx.post(f"{url}/v1/hands", files=upload(short), headers=KEY, timeout=60).status_code == 201
        assert all(p["hand_revision"] == 1 and _close(p, expected_short) for p in plans(url, 16))


def test_the_service_processes_cut_off_slow_clients(tmp_path: Path) -> None:
    """The header deadline reaches every process of ``softsig serve --workers 2`` (its HTTP protocol's setting
    travels with uvicorn's configuration): clients trickling their headers a byte at a time get 408 and a closed
    connection after ``SOFTSIG_HEADER_TIMEOUT`` = 2 s, not the default 10 s."""
    import concurrent.futures

    request = b"GET /readyz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Padding: " + b"a" * 300 + b"\r\n\r\n"
    with serve_workers(tmp_path, tmp_path / "metrics", header_timeout="2") as url:
        port = int(url.rsplit(":", 1)[1])
        with concurrent.futures.ThreadPoolExecutor(6) as pool:
            results = list(pool.map(lambda _: trickle(port, request, interval=0.1, limit=20.0), range(6)))
        assert httpx.get(f"{url}/readyz", timeout=10).status_code == 200  # in-time clients are served
    for answer, closed_after in results:
        assert answer.startswith(b"HTTP/1.1 408 "), answer
        assert closed_after < 7.0, closed_after
