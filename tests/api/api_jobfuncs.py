"""Job callables for the tests of the job machinery (imported by name in the job's own process)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from typing import Any

from softsig_service.errors import InvalidInput
from softsig_service.services.job_process import JobContext


def count(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """Count to n, reporting progress, and write three result files (one in a sub-folder)."""
    n = int(params.get("n", 5))
    for i in range(n):
        time.sleep(float(params.get("dt", 0.05)))
        ctx.progress((i + 1) / n, f"step {i + 1} of {n}")
        if params.get("gate") and i == n // 2:  # wait, half-way, until the test has seen the progress
            gate = ctx.out_dir / "gate"
            while not gate.exists():
                time.sleep(0.02)
    (ctx.out_dir / "report.md").write_text(f"# count\n\n| n | total |\n|---|---|\n| {n} | {n * (n + 1) // 2} |\n")
    (ctx.out_dir / "data.csv").write_text("i,value\n" + "".join(f"{i},{i * i}\n" for i in range(n)))
    (ctx.out_dir / "sub").mkdir(exist_ok=True)
    (ctx.out_dir / "sub" / "result.json").write_text(json.dumps({"n": n}))
    return {"n": n, "total": n * (n + 1) // 2}


def sleep_forever(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """Start a helper process (as a campaign starts workers), record both pids, then never finish."""
    helper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    tmp = ctx.out_dir / "pids.json.tmp"  # written whole, then renamed: a reader never sees half a file
    tmp.write_text(json.dumps({"job": os.getpid(), "helper": helper.pid}))
    tmp.replace(ctx.out_dir / "pids.json")
    ctx.progress(0.25, "sleeping")
    while True:
        time.sleep(0.05)


def fail(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """Fail as bad input does: a SoftsigError naming the field."""
    raise InvalidInput("too many trials for this test", field="trials", value=params.get("trials"), choices=[1, 2])


def crash(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """Die without a word."""
    os._exit(3)


def spawn_workers(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """Use a multiprocessing pool inside the job (campaigns do): the job's process must not be daemonic."""
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(2) as pool:
        squares = pool.map(abs, [-1, -2, -3])
    return {"values": squares}
