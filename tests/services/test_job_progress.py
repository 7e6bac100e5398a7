"""A job's progress reports: throttled to one message per 0.2 s, the final 1.0 always sent, values clipped."""

from __future__ import annotations

import math
import multiprocessing
from pathlib import Path
from types import SimpleNamespace

import pytest

from softsig_service.services import job_process as jobs


def test_progress_is_throttled_and_the_end_always_arrives(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    clock = [100.0]
    # the module's clock only (patching time.monotonic itself would stop every other clock in the process)
    monkeypatch.setattr(jobs, "time", SimpleNamespace(monotonic=lambda: clock[0]))
    receiver, sender = multiprocessing.get_context("spawn").Pipe(duplex=False)
    ctx = jobs.JobContext("j", tmp_path, sender)
    sent: list[tuple[float, str]] = []

    def drain() -> None:
        while receiver.poll():
            kind, fraction, message = receiver.recv()
            assert kind == "progress"
            sent.append((fraction, message))

    ctx.progress(0.1, "a")  # the first report always goes out
    clock[0] += 0.05
    ctx.progress(0.2, "b")  # 0.05 s later: held back
    clock[0] += 0.1
    ctx.progress(0.3, "c")  # 0.15 s after the first: held back
    clock[0] += 0.06
    ctx.progress(0.4, "d")  # 0.21 s after the first: sent
    clock[0] += 0.01
    ctx.progress(1.0, "done")  # the end is never held back
    drain()
    assert sent == [(0.1, "a"), (0.4, "d"), (1.0, "done")]

    sent.clear()
    clock[0] += 1.0
    ctx.progress(7.0, "x")  # clipped to [0, 1]
    clock[0] += 1.0
    ctx.progress(-3.0, "y")
    clock[0] += 1.0
    ctx.progress(math.nan, "z" * 2000)  # not a number: 0; long messages are cut to 500 characters
    drain()
    assert [f for f, _ in sent] == [1.0, 0.0, 0.0] and len(sent[-1][1]) == 500


def test_progress_without_a_connection_is_silent(tmp_path: Path) -> None:
    jobs.JobContext("j", tmp_path, None).progress(0.5, "nobody listens")  # no error, nothing to send to
