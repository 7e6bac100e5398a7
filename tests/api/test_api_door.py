"""Resources are bounded before work: the API key is checked before a body is read, stalled bodies time out,
the marker upload has its own limit and rejected uploads leave no folder (a real uvicorn server on loopback)."""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import uvicorn
from api_helpers import AUTH, KEY, assert_problem, gripper_files, make_settings, trickle, upload
from fastapi.testclient import TestClient
from test_api_serve import free_port

from softsig_service.api.app import create_app
from softsig_service.api.serving import ServiceConfig


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[int, Path]]:
    """A real uvicorn server of the app in a thread: (port, data folder)."""
    data = tmp_path_factory.mktemp("door")
    app = create_app(make_settings(data, body_read_timeout=1.0, body_deadline=3.0, max_markers_bytes=50_000))
    port = free_port()
    config = ServiceConfig(app, host="127.0.0.1", port=port, log_config=None, access_log=False, header_timeout=1.0)
    srv = uvicorn.Server(config)
    thread = threading.Thread(target=srv.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 60
    while not srv.started:
        assert time.monotonic() < deadline and thread.is_alive(), "the server did not start"
        time.sleep(0.05)
    yield port, data
    srv.should_exit = True
    thread.join(timeout=30)


def _raw(port: int, head: str, body: bytes, wait: float = 10.0) -> tuple[int, dict[str, object], float]:
    """Send ``head`` and the part ``body`` of a request, then nothing more; the status, problem and seconds."""
    start = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=wait) as sock:
        sock.sendall(head.encode("latin-1") + b"\r\n" + body)
        data = b""
        while b"\r\n\r\n" not in data or not data.rstrip().endswith(b"}"):
            chunk = sock.recv(65536)
            if not chunk:
                break
            data += chunk
    elapsed = time.monotonic() - start
    status = int(data.split(b" ", 2)[1])
    return status, json.loads(data.split(b"\r\n\r\n", 1)[1]), elapsed


def _head(port: int, path: str, length: int, key: str | None) -> str:
    lines = [f"POST {path} HTTP/1.1", f"Host: 127.0.0.1:{port}", "Content-Type: multipart/form-data; boundary=xx",
             f"Content-Length: {length}"]  # fmt: skip
    if key is not None:
        lines.append(f"X-API-Key: {key}")
    return "\r\n".join(lines) + "\r\n"


@pytest.mark.parametrize("key", [None, "wrong-key"])
def test_unauthenticated_upload_is_refused_before_its_body_is_read(server: tuple[int, Path], key: str | None) -> None:
    port, _ = server
    part = b'--xx\r\nContent-Disposition: form-data; name="manifest"; filename="hand.toml"\r\n\r\n' + b"x" * 65536
    status, body, elapsed = _raw(port, _head(port, "/v1/hands", 100_000_000, key), part)
    assert status == 401 and body["field"] == "X-API-Key", body
    assert elapsed < 5.0  # answered while 99.9 MB of the declared body were never sent


def test_a_stalled_body_times_out(server: tuple[int, Path]) -> None:
    port, _ = server
    status, body, elapsed = _raw(port, _head(port, "/v1/hands", 10_000, KEY), b"--xx\r\n")
    assert status == 408 and body["type"].endswith("request-timeout") and body["field"] == "body", body
    assert elapsed < 8.0


def test_trickled_headers_get_408_and_a_closed_connection(server: tuple[int, Path]) -> None:
    port, _ = server
    request = b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Padding: " + b"a" * 200 + b"\r\n\r\n"
    answer, closed_after = trickle(port, request, interval=0.1, limit=10.0)  # 22 s to send it all
    assert answer.startswith(b"HTTP/1.1 408 "), answer
    assert closed_after < 4.0  # the header timeout is 1 s


def test_a_trickled_body_gets_408_at_its_deadline(server: tuple[int, Path]) -> None:
    port, _ = server
    head = (f"POST /v1/plans HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            f"X-API-Key: {KEY}\r\nContent-Length: 1000\r\n\r\n").encode()  # fmt: skip
    # a byte every 0.25 s never stalls past the 1 s read timeout; the whole body is due within 3 s
    answer, closed_after = trickle(port, b" " * 1000, interval=0.25, limit=15.0, head=head)
    assert answer.startswith(b"HTTP/1.1 408 "), answer
    problem = json.loads(answer.split(b"\r\n\r\n", 1)[1])
    assert problem["field"] == "body" and problem["value"] == 3.0 and "whole" in problem["detail"], problem
    assert closed_after < 7.0


def test_every_request_of_a_kept_alive_connection_has_its_own_header_time(server: tuple[int, Path]) -> None:
    port, _ = server
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        for _ in range(4):  # 2.4 s on one connection, longer than the 1 s header timeout
            sock.sendall(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            data = b""
            while b"\r\n\r\n" not in data or not data.endswith(b"}"):
                chunk = sock.recv(65536)
                assert chunk, "the service closed a connection that was in time"
                data += chunk
            assert data.startswith(b"HTTP/1.1 200 "), data
            time.sleep(0.6)


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, Path]]:
    data = tmp_path_factory.mktemp("door-app")
    with TestClient(create_app(make_settings(data, max_markers_bytes=50_000))) as client:
        yield client, data


def test_marker_upload_has_its_own_limit(api: tuple[TestClient, Path]) -> None:
    client, _ = api
    big = b"time,point,x,y,z\n" + b"0,a,0,0,0\n" * 6000
    response = client.post("/v1/hands/parallel_gripper/signatures/markers", files={"file": ("m.csv", big)},
                           headers=AUTH)  # fmt: skip
    body = assert_problem(response, 413, "body")
    assert body["limit"] == 50_000


def test_rejected_uploads_leave_no_folders(api: tuple[TestClient, Path]) -> None:
    client, data = api
    files = gripper_files("left_behind", with_mesh=False)
    files["parallel_gripper.xml"] = b"<mujoco><worldbody><body name='x'/></worldbody></mujoco>"
    assert_problem(client.post("/v1/hands", files=upload(files), headers=AUTH), 422)
    files = gripper_files("left_behind", with_mesh=False)
    files.update({"a": b"1", "a/b.stl": b"2"})
    assert_problem(client.post("/v1/hands", files=upload(files), headers=AUTH), 422, "assets[1]")
    assert not (data / "hands" / "left_behind").exists()
    assert list((data / "hands").iterdir()) == []


def test_a_body_the_app_never_reads_is_not_waited_for(server: tuple[int, Path]) -> None:
    """A request answered before its body is read (a 404 off /v1 needs no key) closes its connection: the rest of
    the body, trickled a byte at a time, has no deadline to meet otherwise."""
    port, _ = server
    head = b"POST /nowhere HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 1000000\r\n\r\n"
    answer, closed_after = trickle(port, b"x" * 100, interval=0.2, limit=10.0, head=head)
    assert answer.startswith(b"HTTP/1.1 404 "), answer
    assert closed_after < 4.0


def test_pipelined_headers_have_their_deadline_too(server: tuple[int, Path]) -> None:
    port, _ = server
    first = b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    second = b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Padding: " + b"a" * 200 + b"\r\n\r\n"
    answer, closed_after = trickle(port, second[10:], interval=0.1, limit=10.0, head=first + second[:10])
    assert answer.startswith(b"HTTP/1.1 200 ") and b"408 Request Timeout" in answer, answer
    assert closed_after < 4.0
