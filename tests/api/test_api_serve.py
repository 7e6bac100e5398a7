"""``softsig serve`` as a user runs it: a subprocess on a free loopback port, driven by the Python client; a
restart keeps the registry; concurrent writes over real HTTP lose nothing."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from api_helpers import KEY, gripper_files

from softsig_service.api.client import ApiError, SoftsigClient

STARTUP_TIMEOUT = 60.0


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def serve(data_dir: Path, db: Path) -> Iterator[SoftsigClient]:
    """Start ``softsig serve`` on a free port; yield a client once /healthz answers; stop it in any case."""
    port = free_port()
    env = {**os.environ, "SOFTSIG_DATA_DIR": str(data_dir), "SOFTSIG_API_KEYS": f"other-key,{KEY}",
           "SOFTSIG_WARM_PLANNER": "false"}  # fmt: skip
    cmd = [sys.executable, "-m", "softsig_service.cli", "serve", "--host", "127.0.0.1", "--port", str(port),
           "--db", str(db)]  # fmt: skip
    log = open(data_dir / f"serve-{port}.log", "wb")  # noqa: SIM115
    proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
    client = SoftsigClient(f"http://127.0.0.1:{port}", api_key=KEY, timeout=60.0)
    try:
        deadline = time.monotonic() + STARTUP_TIMEOUT
        while not client.health():
            if proc.poll() is not None:
                raise AssertionError(f"softsig serve exited with {proc.returncode}")
            if time.monotonic() > deadline:
                raise AssertionError(f"softsig serve did not answer within {STARTUP_TIMEOUT} s")
            time.sleep(0.1)
        yield client
    finally:
        client.close()
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
        log.close()


def test_serve_drive_restart(tmp_path: Path) -> None:
    db = tmp_path / "registry" / "softsig.sqlite3"
    with serve(tmp_path, db) as api:
        assert api.ready().status == "ready"
        assert {"pisa_iit_softhand", "sdm_hand"} <= {h.name for h in api.hands().items}
        files = gripper_files("served_gripper")
        hand = api.register_hand(
            ("hand.toml", files["hand.toml"]),
            ("parallel_gripper.xml", files["parallel_gripper.xml"]),
            [(rel, (rel, data)) for rel, data in files.items() if rel not in ("hand.toml", "parallel_gripper.xml")],
        )
        assert hand.etag.startswith('"served_gripper.r1.')
        sig = api.compute_closure_signature("served_gripper", "ellipsoid")
        assert sig.version == 1
        plan = api.plan(hand="served_gripper", object={"kind": "builtin", "name": "box"}, strategy="C")
        assert plan.success and plan.id is not None and plan.grasp_pose is not None
        png = api.plan_image(plan.id)
        assert png.startswith(b"\x89PNG")
        robust = api.plan(hand="parallel_gripper", object={"kind": "builtin", "name": "box"}, strategy="R",
                          sigma_r=0.1, sigma_t=0.01, store=False)  # fmt: skip
        assert robust.strategy == "R" and robust.quality is not None
        ranked = api.plan(hand="parallel_gripper", object={"kind": "builtin", "name": "box"}, strategy="S",
                          candidates=3, output_frame="base", store=False)  # fmt: skip
        assert len(ranked.grasps) == 3 and ranked.output_frame == "base"
        assert ranked.grasps[0].moveit_grasp.grasp_pose.header.frame_id == "base"
        with pytest.raises(ApiError) as err:
            api.plan(hand="served_gripper", object={"kind": "builtin", "name": "box"}, strategy="Z")  # type: ignore[arg-type]
        assert err.value.status == 422 and err.value.problem.field == "strategy"

        # concurrent writes over HTTP (each thread with its own connection pool)
        errors: list[BaseException] = []

        def writer() -> None:
            with SoftsigClient(api._http.base_url.__str__(), api_key=KEY) as mine:
                for _ in range(3):
                    try:
                        mine.compute_closure_signature("served_gripper", "pca")
                    except BaseException as exc:  # collected, not lost in the thread
                        errors.append(exc)

        threads = [threading.Thread(target=writer) for _ in range(6)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert errors == []
        versions = sorted(s.version for s in api.signatures("served_gripper", limit=500).items)
        assert versions == list(range(1, 20))
    assert db.is_file()

    with serve(tmp_path, db) as api:  # a restart on the same registry keeps everything
        assert api.hand("served_gripper").etag == hand.etag
        assert api.latest_signature("served_gripper").version == 19
        assert api.signature("served_gripper", 1).signature == sig.signature
        again = api.get_plan(plan.id)
        assert again.grasp_pose == plan.grasp_pose
        assert [h.name for h in api.hands().items].count("pisa_iit_softhand") == 1, "built-ins registered once"
        api.delete_hand("served_gripper")
        with pytest.raises(ApiError) as err:
            api.hand("served_gripper")
        assert err.value.status == 404


def test_a_port_in_use_is_named(tmp_path: Path) -> None:
    """``softsig serve`` on a port another process listens on ends at once with a message naming the port."""
    import socket
    import subprocess
    import sys

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        env = {**os.environ, "SOFTSIG_DATA_DIR": str(tmp_path), "SOFTSIG_WARM_PLANNER": "false"}
        res = subprocess.run(
            [sys.executable, "-m", "softsig_service.cli", "serve", "--port", str(port), "--workers", "1"],
            capture_output=True, text=True, timeout=120, env=env,
        )  # fmt: skip
    assert res.returncode == 2, (res.stdout, res.stderr)
    assert f"port {port} on 127.0.0.1 is already in use" in res.stderr and "--port" in res.stderr, res.stderr
