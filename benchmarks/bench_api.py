"""Plan requests over HTTP against a ``softsig serve`` subprocess on loopback: throughput and latency percentiles.

Run: .venv/bin/python benchmarks/bench_api.py [--requests 400] [--concurrency 8] [--seconds 60] [--strategy C]
     [--workers N]   (service processes, default: every CPU)
     .venv/bin/python benchmarks/bench_api.py --per-request --workers 2 --requests 400 --client stdlib
                     (server CPU per request, one at a time: the health check, a hand, a rejected body, a stored
                     plan read back, plans; beside the framework's floor, a bare FastAPI app with one route on the
                     same uvicorn, uvloop and httptools with as many processes (floor_app.py), and each as a
                     multiple of it against its target)
     .venv/bin/python benchmarks/bench_api.py --baseline 5354fe9 --rounds 3 --client stdlib
                     (also the service of an earlier revision, exported with ``git archive`` and served from its
                     own folder; A B A B ... in turn, a fresh data folder per run; with ``--per-request`` too, both
                     against the one floor measured first)

The server runs on a free loopback port with a fresh data folder (SQLite registry inside). Each client thread keeps
one HTTP/1.1 connection (httpx; with ``--client stdlib`` the standard library's ``http.client`` with the bodies
encoded beforehand, a load generator that leaves more of a small machine's CPU to the server) and posts ``POST
/v1/plans`` for the built-in box at random poses (x in [0.4, 0.6] m, y in [-0.15, 0.15] m, yaw in [-pi, pi]; fixed
seed) until ``--requests`` are done or ``--seconds`` have passed. Printed per run: requests per second, p50/p90/p99
latency [ms] measured by the client, the mean planner time per plan (from each plan's ``timing``), the mean time in
the HTTP stack per request from the service's Prometheus metrics (every process's together; so the rest is queueing
and the client), and the CPU used by the client process and by the server's processes over the run, in cores. Runs:
concurrency 1 (the latency of one request alone), then ``--concurrency`` with plans stored and with ``store:
false``.
"""

from __future__ import annotations

import argparse
import contextlib
import http.client
import json
import math
import os
import random
import re
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Protocol
from urllib.parse import urlsplit

import httpx
from baseline_tree import export_revision, tree_env

KEY = "bench-key"


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def start_server(data: Path, workers: int, tree: Path | None = None) -> tuple[subprocess.Popen[bytes], str]:
    """``softsig serve`` of the package in ``tree`` (None: the working tree) on a free loopback port; (process,
    URL) once it answers ``/readyz``."""
    port = free_port()
    env, cwd = tree_env(tree)
    env.update(SOFTSIG_DATA_DIR=str(data), SOFTSIG_API_KEYS=KEY, SOFTSIG_LOG_LEVEL="warning")
    cmd = [sys.executable, "-m", "softsig_service.cli", "serve", "--host", "127.0.0.1", "--port", str(port),
           "--workers", str(workers)]  # fmt: skip
    proc = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"{url}/readyz", timeout=1).status_code == 200:
                return proc, url
        except httpx.HTTPError:
            pass
        if proc.poll() is not None:
            raise SystemExit(f"softsig serve exited with {proc.returncode}")
        time.sleep(0.1)
    proc.kill()
    raise SystemExit("softsig serve did not become ready within 60 s")


def metric_sum_count(text: str, name: str, label: str = "") -> tuple[float, float]:
    total = count = 0.0
    for line in text.splitlines():
        if label and label not in line:
            continue
        if m := re.match(rf"{name}_sum(\{{[^}}]*\}})? ([0-9.eE+-]+)$", line):
            total += float(m.group(2))
        elif m := re.match(rf"{name}_count(\{{[^}}]*\}})? ([0-9.eE+-]+)$", line):
            count += float(m.group(2))
    return total, count


def process_cpu_seconds(pid: int) -> float:
    """User + system CPU time [s] of process ``pid`` and every living process below it (the service's worker
    processes), with their waited-for children (Linux ``/proc/<pid>/stat``)."""
    stats: dict[int, list[str]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stats[int(entry)] = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
    tree, frontier = {pid}, {pid}
    while frontier:
        frontier = {p for p, f in stats.items() if int(f[1]) in frontier and p not in tree}
        tree |= frontier
    return sum(int(v) for p in tree if p in stats for v in stats[p][11:15]) / os.sysconf("SC_CLK_TCK")


def wait_idle(pid: int, *, below: float = 0.05, timeout: float = 120.0) -> None:
    """Wait until the server's processes use less than ``below`` cores over a second (its worker processes have
    finished starting), so that their start-up does not count against the first run."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        before = process_cpu_seconds(pid)
        time.sleep(1.0)
        if process_cpu_seconds(pid) - before < below:
            return


def plan_body(rng: random.Random, strategy: str, store: bool) -> dict[str, Any]:
    """A ``POST /v1/plans`` body: the SoftHand, the built-in box at a random pose drawn from ``rng`` (x in [0.4,
    0.6] m, y in [-0.15, 0.15] m, yaw in [-pi, pi])."""
    pose = {"x": rng.uniform(0.4, 0.6), "y": rng.uniform(-0.15, 0.15), "yaw": rng.uniform(-math.pi, math.pi)}
    return {"hand": "pisa_iit_softhand", "object": {"kind": "builtin", "name": "box", "pose": pose},
            "strategy": strategy, "store": store}  # fmt: skip


class Poster(Protocol):
    """One client connection that posts JSON bodies: (status, response body)."""

    def post(self, path: str, body: dict[str, Any], encoded: bytes) -> tuple[int, bytes]: ...

    def get(self, path: str) -> tuple[int, bytes]: ...

    def close(self) -> None: ...


class HttpxPoster:
    """httpx, encoding each body as it posts it."""

    def __init__(self, url: str) -> None:
        self.client = httpx.Client(base_url=url, headers={"X-API-Key": KEY}, timeout=30)

    def post(self, path: str, body: dict[str, Any], encoded: bytes) -> tuple[int, bytes]:
        r = self.client.post(path, json=body)
        return r.status_code, r.content

    def get(self, path: str) -> tuple[int, bytes]:
        r = self.client.get(path)
        return r.status_code, r.content

    def close(self) -> None:
        self.client.close()


class StdlibPoster:
    """The standard library's ``http.client`` on one kept-alive connection, posting bodies encoded beforehand (head
    and body leave in one ``send``)."""

    def __init__(self, url: str) -> None:
        parts = urlsplit(url)
        self.conn = http.client.HTTPConnection(parts.hostname or "127.0.0.1", parts.port, timeout=30)
        self.headers = {"X-API-Key": KEY, "Content-Type": "application/json"}

    def post(self, path: str, body: dict[str, Any], encoded: bytes) -> tuple[int, bytes]:
        self.conn.request("POST", path, body=encoded, headers=self.headers)
        r = self.conn.getresponse()
        return r.status, r.read()

    def get(self, path: str) -> tuple[int, bytes]:
        self.conn.request("GET", path, headers=self.headers)
        r = self.conn.getresponse()
        return r.status, r.read()

    def close(self) -> None:
        self.conn.close()


CLIENTS: dict[str, type[HttpxPoster] | type[StdlibPoster]] = {"httpx": HttpxPoster, "stdlib": StdlibPoster}


def run(
    url: str,
    *,
    n: int,
    concurrency: int,
    seconds: float,
    strategy: str,
    store: bool,
    server_pid: int,
    client: str = "httpx",
) -> dict[str, Any]:
    rng = random.Random(7)
    bodies = [plan_body(rng, strategy, store) for _ in range(n)]
    encoded = [json.dumps(b).encode() for b in bodies]
    latencies: list[float] = []
    planner: list[float] = []  # [s] the planner's own time, from each plan's timing
    failures: list[str] = []
    lock = threading.Lock()
    next_index = 0
    deadline = time.monotonic() + seconds

    def worker() -> None:
        nonlocal next_index
        poster: Poster = CLIENTS[client](url)
        try:
            while time.monotonic() < deadline:
                with lock:
                    if next_index >= n:
                        return
                    i = next_index
                    next_index += 1
                t0 = time.perf_counter()
                status, content = poster.post("/v1/plans", bodies[i], encoded[i])
                dt = time.perf_counter() - t0
                with lock:
                    if status == (201 if store else 200):  # a plan not stored is 200 OK
                        latencies.append(dt)
                        planner.append(json.loads(content)["timing"]["total"])
                    else:
                        failures.append(f"{status} {content[:200]!r}")
        finally:
            poster.close()

    before = httpx.get(f"{url}/metrics").text
    cpu_client, cpu_server = time.process_time(), process_cpu_seconds(server_pid)
    t0 = time.perf_counter()
    threads = [threading.Thread(target=worker) for _ in range(concurrency)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.perf_counter() - t0
    cpu_client, cpu_server = time.process_time() - cpu_client, process_cpu_seconds(server_pid) - cpu_server
    after = httpx.get(f"{url}/metrics").text
    http_s = [
        a - b
        for a, b in zip(
            metric_sum_count(after, "softsig_http_request_duration_seconds", 'route="/v1/plans"'),
            metric_sum_count(before, "softsig_http_request_duration_seconds", 'route="/v1/plans"'),
            strict=True,
        )
    ]
    lat = sorted(latencies)

    def pct(p: float) -> float:
        return lat[min(len(lat) - 1, round(p / 100 * (len(lat) - 1)))] * 1e3 if lat else float("nan")

    return {
        "concurrency": concurrency,
        "store": store,
        "requests": len(lat),
        "failures": len(failures),
        "first_failure": failures[0] if failures else "",
        "rps": len(lat) / wall if wall > 0 else 0.0,
        "p50": pct(50),
        "p90": pct(90),
        "p99": pct(99),
        "mean": statistics.fmean(lat) * 1e3 if lat else float("nan"),
        "planner_mean": statistics.fmean(planner) * 1e3 if planner else float("nan"),
        "server_mean": http_s[0] / http_s[1] * 1e3 if http_s[1] > 0 else float("nan"),
        "client_cpu": cpu_client / wall if wall > 0 else float("nan"),
        "server_cpu": cpu_server / wall if wall > 0 else float("nan"),
    }


def start_floor(workers: int) -> tuple[subprocess.Popen[bytes], str]:
    """The bare FastAPI app of ``floor_app.py`` on uvicorn (uvloop, httptools) with ``workers`` processes on a free
    loopback port; (process, URL) once it answers."""
    port = free_port()
    cmd = [sys.executable, "-m", "uvicorn", "floor_app:app", "--host", "127.0.0.1", "--port", str(port),
           "--workers", str(workers), "--loop", "uvloop", "--http", "httptools", "--log-level", "warning",
           "--no-access-log"]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=Path(__file__).parent, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        with contextlib.suppress(httpx.HTTPError):
            if httpx.get(f"{url}/floor", timeout=1).status_code == 200:
                return proc, url
        time.sleep(0.1)
    proc.kill()
    raise SystemExit("the floor app did not answer within 60 s")


def measure(server_pid: int, n: int, call: Any) -> tuple[float, float, float]:
    """(wall, server CPU, client CPU) [ms] per call of ``call``, ``n`` calls one after the other."""
    cpu_server, cpu_client, t0 = process_cpu_seconds(server_pid), time.process_time(), time.perf_counter()
    for _ in range(n):
        call()
    wall = time.perf_counter() - t0
    cpu_server, cpu_client = process_cpu_seconds(server_pid) - cpu_server, time.process_time() - cpu_client
    return wall / n * 1e3, cpu_server / n * 1e3, cpu_client / n * 1e3


def floor_cost(workers: int, n: int, client: str) -> float:
    """Server CPU [ms] per ``GET /floor`` of the bare app (:func:`start_floor`), one request at a time."""
    proc, url = start_floor(workers)
    poster: Poster = CLIENTS[client](url)
    try:
        wait_idle(proc.pid)
        measure(proc.pid, 50, lambda: poster.get("/floor"))  # warm-up
        return measure(proc.pid, n, lambda: poster.get("/floor"))[1]
    finally:
        poster.close()
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()


PER_REQUEST_TARGETS: dict[str, float] = {"GET /healthz": 1.5, "GET /v1/hands/{hand}": 2.5, "GET /v1/plans/{id}": 2.5}
"""Server CPU per request as a multiple of the floor's, at most (POST /v1/plans: the planner's time + 2.5 floors)."""
POST_TARGET = 2.5


def per_request(
    url: str, server_pid: int, n: int, strategy: str, client: str = "httpx", floor: float | None = None
) -> None:
    """Print wall time and server CPU [ms] per request, one request at a time, for the health check, a hand, a request
    that fails validation, a stored plan read back (a plan's response without planning), and plans not stored and
    stored: what the HTTP stack costs beside the planner. With ``floor`` (the bare app's server CPU [ms] per request)
    also each as a multiple of it, against :data:`PER_REQUEST_TARGETS`."""
    rng = random.Random(11)
    poster: Poster = CLIENTS[client](url)
    planner: list[float] = []

    def post(body: dict[str, Any]) -> tuple[int, bytes]:
        status, content = poster.post("/v1/plans", body, json.dumps(body).encode())
        if status in (200, 201):
            planner.append(json.loads(content)["timing"]["total"] * 1e3)
        return status, content

    try:
        stored = json.loads(post(plan_body(rng, strategy, True))[1])["links"]["self"]
        cases = (
            ("GET /healthz", lambda: poster.get("/healthz")),
            ("GET /v1/hands/{hand}", lambda: poster.get("/v1/hands/pisa_iit_softhand")),
            ("POST /v1/plans, invalid body", lambda: post({"hand": "x"})),
            ("GET /v1/plans/{id}", lambda: poster.get(stored)),
            ("POST /v1/plans, not stored", lambda: post(plan_body(rng, strategy, False))),
            ("POST /v1/plans, stored", lambda: post(plan_body(rng, strategy, True))),
        )
        print(f"one request at a time, {n} each, strategy {strategy}, client {client}")
        head = f"{'request':30s} {'wall ms':>8} {'server CPU ms':>13} {'client CPU ms':>13}"
        print(head + (f" {'x floor':>8} {'target':>8}" if floor else ""))
        if floor:
            print(f"{'floor: bare FastAPI, GET /floor':30s} {'':>8} {floor:13.2f}")
        for name, call in cases:
            planner.clear()
            wall, server, client_cpu = measure(server_pid, n, call)
            line = f"{name:30s} {wall:8.2f} {server:13.2f} {client_cpu:13.2f}"
            if floor and name in PER_REQUEST_TARGETS:
                line += f" {server / floor:8.2f} {'<= ' + str(PER_REQUEST_TARGETS[name]):>8}"
            elif floor and planner:
                plan_ms = statistics.fmean(planner)
                line += f" {(server - plan_ms) / floor:8.2f} {'<= ' + str(POST_TARGET):>8}"
                line += f"  (planner {plan_ms:.2f} ms; x floor of the rest)"
            print(line)
    finally:
        poster.close()


def print_row(side: str, r: dict[str, Any]) -> None:
    """One line of the table (``side``: which package served it)."""
    print(f"{side:>10} {r['concurrency']:4d} {('yes' if r['store'] else 'no'):>5} {r['requests']:5d} "
          f"{r['failures']:4d} {r['rps']:7.1f} {r['p50']:7.2f} {r['p90']:7.2f} {r['p99']:7.2f} "
          f"{r['planner_mean']:10.2f} {r['server_mean']:9.2f} {r['client_cpu']:10.2f} {r['server_cpu']:10.2f}",
          flush=True)  # fmt: skip
    if r["first_failure"]:
        print(f"     first failure: {r['first_failure']}")


@contextlib.contextmanager
def serving(data: Path, workers: int, tree: Path | None, strategy: str) -> Iterator[tuple[str, int]]:
    """A started, idle, warmed-up service of the package in ``tree`` (None: the working tree) with its data in
    ``data``: (URL, server process id); stopped at the end."""
    proc, url = start_server(data, workers, tree)
    try:
        wait_idle(proc.pid)
        run(url, n=30, concurrency=2, seconds=30, strategy=strategy, store=True, server_pid=proc.pid)  # warm-up
        yield url, proc.pid
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()


def in_turn(
    args: argparse.Namespace,
) -> Iterator[tuple[str, int, contextlib.AbstractContextManager[tuple[str, int]]]]:
    """The sides to measure, ``--rounds`` times in turn (the ``--baseline`` revision first, then this tree), each as
    (its name, the round, its service to enter: :func:`serving` with a data folder of its own)."""
    with tempfile.TemporaryDirectory(prefix="softsig-bench-") as tmp:
        sides: list[tuple[str, Path | None]] = [("this tree", None)]
        if args.baseline is not None:
            sides.insert(0, (args.baseline[:10], export_revision(args.baseline, Path(tmp))))
        for r in range(args.rounds):
            for i, (name, tree) in enumerate(sides):
                yield name, r, serving(Path(tmp) / f"data-{r}-{i}", args.workers, tree, args.strategy)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--requests", type=int, default=400, help="requests per run")
    parser.add_argument("--concurrency", type=int, default=8)
    parser.add_argument("--seconds", type=float, default=60.0, help="time cap per run [s]")
    parser.add_argument("--strategy", choices=("S", "C"), default="C")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="softsig serve --workers")
    parser.add_argument(
        "--client", choices=tuple(CLIENTS), default="httpx", help="the load generator's HTTP client (see above)"
    )
    parser.add_argument(
        "--per-request", action="store_true", help="instead: wall time and server CPU per request, one at a time"
    )
    parser.add_argument("--baseline", metavar="REV", help="also serve the package at this git revision (see above)")
    parser.add_argument("--rounds", type=int, default=1, help="runs of each side, in turn (A B A B ...)")
    args = parser.parse_args()
    if args.per_request:
        floor = floor_cost(args.workers, args.requests, args.client)
        for name, r, served in in_turn(args):
            if args.baseline is not None:
                print(f"\n{name} (round {r + 1})", flush=True)
            with served as (url, pid):
                per_request(url, pid, args.requests, args.strategy, args.client, floor)
        return
    print(f"POST /v1/plans, strategy {args.strategy}, pisa_iit_softhand, box at random poses; {os.cpu_count()} CPUs, "
          f"{args.workers} service processes, client {args.client}")  # fmt: skip
    print(f"{'side':>10} {'conc':>4} {'store':>5} {'n':>5} {'fail':>4} {'req/s':>7} {'p50 ms':>7} {'p90 ms':>7} "
          f"{'p99 ms':>7} {'planner ms':>10} {'server ms':>9} {'client CPU':>10} {'server CPU':>10}")  # fmt: skip
    # (requests, concurrency, stored): one request at a time, then --concurrency with plans stored and not
    runs = ((max(50, args.requests // 4), 1, True), (args.requests, args.concurrency, True),
            (args.requests, args.concurrency, False))  # fmt: skip
    for name, _r, served in in_turn(args):
        with served as (url, pid):
            for n, concurrency, store in runs:
                print_row(
                    name,
                    run(
                        url,
                        n=n,
                        concurrency=concurrency,
                        seconds=args.seconds,
                        strategy=args.strategy,
                        store=store,
                        server_pid=pid,
                        client=args.client,
                    ),
                )
    print("planner ms: mean planner time per plan (each plan's timing.total); server ms: mean time the request")
    print("spent in the server's HTTP stack (softsig_http_request_duration_seconds, route /v1/plans, all processes).")
    print("client CPU / server CPU: CPU time of the client process / of every server process over the run's wall")
    print("time, in cores (on a 2-core machine the client's share is taken from the server).")


if __name__ == "__main__":
    main()
