"""Crashes leave nothing behind: after ``kill -9`` of ``softsig serve``, its compute-pool worker, its job process
(which leads its own process group) and the multiprocessing resource tracker end within seconds."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

from api_helpers import pid_alive, wait_for
from test_api_serve import serve

BOX = {"kind": "builtin", "name": "box"}


def _ppid(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            return int(f.read().rsplit(")", 1)[1].split()[1])
    except (FileNotFoundError, ProcessLookupError, ValueError):
        return None


def descendants(root: int) -> set[int]:
    """Every living process below ``root``."""
    pids = [int(p) for p in os.listdir("/proc") if p.isdigit()]
    parent = {pid: _ppid(pid) for pid in pids}
    found: set[int] = set()
    frontier = {root}
    while frontier:
        children = {pid for pid, pp in parent.items() if pp in frontier and pid not in found}
        found |= children
        frontier = children
    return {pid for pid in found if pid_alive(pid)}


def test_children_die_with_the_service(tmp_path: Path) -> None:
    with serve(tmp_path, tmp_path / "registry.sqlite3") as api:
        service = next(p for p in descendants(os.getpid()) if "serve" in Path(f"/proc/{p}/cmdline").read_text())
        job = api.submit_validation(hand="parallel_gripper", object=BOX, strategy="S", trials=2000)
        wait_for(lambda: api.job(job.id).status == "running", timeout=120)
        children = wait_for(lambda: (lambda d: d if len(d) >= 3 else None)(descendants(service)), timeout=60)
        os.kill(service, signal.SIGKILL)
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and any(pid_alive(p) for p in children):
            time.sleep(0.2)
        left = [p for p in children if pid_alive(p)]
        assert not left, [Path(f"/proc/{p}/cmdline").read_bytes() for p in left]


def test_workers_die_with_a_killed_supervisor(tmp_path: Path) -> None:
    """``softsig serve --workers 2``: a ``kill -9`` of the supervisor (what a container runtime does) leaves no
    worker answering on the port, not even for a moment."""
    import socket
    import subprocess
    import sys

    import httpx

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {**os.environ, "SOFTSIG_DATA_DIR": str(tmp_path), "SOFTSIG_WARM_PLANNER": "false"}
    cmd = [sys.executable, "-m", "softsig_service.cli", "serve", "--workers", "2", "--port", str(port)]
    log = (tmp_path / "serve.log").open("w")
    proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}/healthz"
    try:

        def answers() -> bool:
            try:
                return httpx.get(url, timeout=5).status_code == 200
            except httpx.HTTPError:
                return False

        wait_for(answers, timeout=180, poll=0.2)
        workers = wait_for(lambda: (lambda d: d if len(d) >= 2 else None)(descendants(proc.pid)), timeout=60)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
        assert not answers(), "a worker still answers after its supervisor was killed"
        wait_for(lambda: not any(pid_alive(p) for p in workers), timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
        log.close()
