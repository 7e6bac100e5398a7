"""The job's own process: what runs there (:func:`job_main`), the :class:`JobContext` a job callable gets, and how
the service stops the process with the workers it started (:func:`kill_group`).

A job runs ``"module:function"`` as ``fn(params, ctx) -> dict`` in a process of its own (its own process group)
that dies with the service; its outcome goes back over a pipe as ``("result", dict)``, ``("error", problem)`` or
``("crash", message, traceback)``, its progress as ``("progress", fraction, message)``.
"""

from __future__ import annotations

import contextlib
import importlib
import math
import os
import signal
import time
import traceback
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

from softsig_service.errors import SoftsigError
from softsig_service.services.compute import _worker_init, error_payload
from softsig_service.services.lifeline import follow_parent
from softsig_service.services.serialize import to_jsonable


class JobContext:
    """What a job callable gets besides its parameters: its result folder and a progress reporter."""

    def __init__(self, job_id: str, out_dir: Path, conn: Connection | None) -> None:
        self.job_id = job_id
        self.out_dir = out_dir
        self._conn = conn
        self._last = -math.inf
        self._last_fraction = -1.0

    def progress(self, fraction: float, message: str = "") -> None:
        """Report progress in [0, 1] (sent at most every 0.2 s, and always when it reaches 1)."""
        f = min(max(float(fraction), 0.0), 1.0) if math.isfinite(fraction) else 0.0
        now = time.monotonic()
        if self._conn is None or (now - self._last < 0.2 and f < 1.0):
            return
        self._last, self._last_fraction = now, f
        with contextlib.suppress(OSError, ValueError):
            self._conn.send(("progress", f, str(message)[:500]))


def job_main(job_id: str, target: str, params: dict[str, Any], out_dir: str, conn: Connection) -> None:
    """Entry point of a job's process."""
    with contextlib.suppress(OSError, AttributeError):
        os.setpgrp()  # its own process group: killing the group stops the workers it starts
    follow_parent(whole_group=True)  # the job and its workers die with the service
    _worker_init()
    try:
        module, _, name = target.partition(":")
        fn = getattr(importlib.import_module(module), name)
        result = fn(params, JobContext(job_id, Path(out_dir), conn))
        conn.send(("result", to_jsonable(result if result is not None else {})))
    except SoftsigError as exc:
        conn.send(("error", error_payload(exc)))
    except BaseException as exc:
        conn.send(("crash", f"{type(exc).__name__}: {exc}", traceback.format_exc()[-4000:]))
    finally:
        conn.close()


def kill_group(proc: BaseProcess) -> None:
    """Stop a job's process and its process group (SIGTERM, then SIGKILL), waiting up to 2 s for each."""
    pid = proc.pid
    if pid is None:
        return
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(pid, sig)
        except (ProcessLookupError, PermissionError):
            with contextlib.suppress(Exception):
                proc.terminate() if sig == signal.SIGTERM else proc.kill()
        except OSError:
            pass
        proc.join(2.0)
        if not proc.is_alive():
            # the group may outlive its leader: make sure the rest is gone too
            with contextlib.suppress(OSError):
                os.killpg(pid, signal.SIGKILL)
            return
