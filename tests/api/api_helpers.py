"""Helpers of the API tests: settings of a test service, a user hand to upload, problem and polling checks."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from softsig_service.config import REPO_HANDS_DIR, Settings
from softsig_service.services.jobs import JobKind

KEY = "test-key-0123456789"
AUTH = {"X-API-Key": KEY}
TEST_JOB_KINDS = {
    name: JobKind(name, f"api_jobfuncs:{name}") for name in ("count", "sleep_forever", "fail", "crash", "spawn_workers")
}

TET_OBJ = b"""# a small tetrahedron [m]
v 0 0 0
v 0.01 0 0
v 0 0.01 0
v 0 0 0.01
f 1 3 2
f 1 2 4
f 1 4 3
f 2 3 4
"""


def make_settings(data_dir: Path, **overrides: Any) -> Settings:
    """Settings of a test service: its own data folder (SQLite file inside), one API key, one compute worker."""
    values: dict[str, Any] = {"data_dir": data_dir, "api_keys": [KEY], "compute_workers": 1, "warm_planner": False}
    values.update(overrides)
    return Settings(**values)


def gripper_files(name: str = "test_gripper", *, with_mesh: bool = True) -> dict[str, bytes]:
    """A user hand made from the built-in parallel gripper (renamed), optionally with a mesh asset
    ``meshes/tet.obj`` on its mount body."""
    src = REPO_HANDS_DIR / "parallel_gripper"
    manifest = (src / "hand.toml").read_text(encoding="utf-8").replace('name = "parallel_gripper"', f'name = "{name}"')
    model = (src / "parallel_gripper.xml").read_text(encoding="utf-8")
    files = {
        "hand.toml": manifest.encode(),
        "parallel_gripper.xml": model.encode(),
        "scene.xml": (src / "scene.xml").read_bytes(),
    }
    if with_mesh:
        head = '<mujoco model="parallel_gripper">'
        assert head in model
        model = model.replace(head, head + '\n  <asset><mesh name="tet" file="meshes/tet.obj"/></asset>', 1)
        mount = '<body name="mount"'
        k = model.index(mount)
        end = model.index(">", k) + 1
        model = (
            model[:end]
            + '\n      <geom type="mesh" mesh="tet" contype="0" conaffinity="0" mass="0.001"/>'
            + model[end:]
        )
        files["parallel_gripper.xml"] = model.encode()
        files["meshes/tet.obj"] = TET_OBJ
    return files


def upload(files: dict[str, bytes]) -> list[tuple[str, tuple[str, bytes]]]:
    """The multipart parts of a hand upload made of ``files`` (manifest, model, the rest as assets)."""
    parts = [
        ("manifest", ("hand.toml", files["hand.toml"])),
        ("model", ("parallel_gripper.xml", files["parallel_gripper.xml"])),
    ]
    for rel, data in files.items():
        if rel not in ("hand.toml", "parallel_gripper.xml"):
            parts.append(("assets", (rel, data)))
    return parts


def assert_problem(response: Any, status: int, field: str | None = None) -> dict[str, Any]:
    """The response is an RFC 9457 problem with ``status`` (and naming ``field``); returns its body."""
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith("application/problem+json"), response.headers
    body: dict[str, Any] = response.json()
    assert body["status"] == status and body["type"].startswith("urn:softsig:problem:") and body["title"]
    if field is not None:
        assert body.get("field") == field, body
    return body


def wait_for(predicate: Callable[[], Any], timeout: float = 180.0, poll: float = 0.05) -> Any:
    """Poll ``predicate`` until it returns something truthy (or fail after ``timeout`` [s]: generous, since a
    spawned job process imports MuJoCo and the machine may be busy; a healthy wait returns at once)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(poll)
    raise AssertionError(f"condition not met within {timeout} s")


def pid_alive(pid: int) -> bool:
    """Whether a process runs (zombies count as dead)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            state = f.read().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state not in ("Z", "X")


def trickle(port: int, data: bytes, interval: float, limit: float, head: bytes = b"") -> tuple[bytes, float]:
    """Send ``head`` at once, then ``data`` one byte every ``interval`` seconds to the service on ``port``, as a
    slow client does, reading whatever it answers; stops when the service closes the connection or after ``limit`` seconds. Returns what the
    service sent and the seconds until it closed (``limit`` when it never did)."""
    import socket

    start = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=limit) as sock:
        sock.sendall(head)
        sock.setblocking(False)
        answer = b""
        for byte in data:
            if time.monotonic() - start > limit:
                return answer, limit
            try:
                sock.sendall(bytes([byte]))
            except OSError:  # closed by the service
                break
            time.sleep(interval)
            try:
                chunk = sock.recv(65536)
            except BlockingIOError:
                continue
            except OSError:
                break
            if not chunk:
                return answer, time.monotonic() - start
            answer += chunk
        sock.settimeout(max(limit - (time.monotonic() - start), 0.01))
        try:
            while chunk := sock.recv(65536):
                answer += chunk
        except TimeoutError:
            return answer, limit
        except OSError:
            pass
    return answer, time.monotonic() - start
