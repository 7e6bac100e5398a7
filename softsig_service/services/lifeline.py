"""Children die with their parent: a worker process (compute pool, job) that outlives the service would keep
computing and writing into a registry that has moved on.

:func:`follow_parent` starts a daemon thread in the child that checks every ``interval`` seconds whether its
parent is still the process that started it (after the parent dies the child is re-parented, so ``getppid``
changes); then it kills its own process group (a job's process leads one, holding the workers it started) or
only itself, at once, with ``SIGKILL``. A check rather than ``PR_SET_PDEATHSIG``: that signal follows the parent
*thread*, and the service starts its children from pool threads that may end while the child still runs.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time

CHECK_INTERVAL = 0.5
"""Seconds between two looks at the parent."""


def _watch(parent: int, interval: float, whole_group: bool) -> None:
    while os.getppid() == parent:
        time.sleep(interval)
    if whole_group and os.getpgrp() == os.getpid():
        with contextlib.suppress(OSError):
            os.killpg(os.getpid(), signal.SIGKILL)
    os.kill(os.getpid(), signal.SIGKILL)


def follow_parent(*, whole_group: bool = False, interval: float = CHECK_INTERVAL) -> None:
    """Kill this process (``whole_group``: its process group, when it leads one) as soon as its parent dies."""
    parent = os.getppid()
    if parent <= 1:  # already orphaned (or started by init): nothing to follow
        os.kill(os.getpid(), signal.SIGKILL)
    threading.Thread(target=_watch, args=(parent, interval, whole_group), name="softsig-lifeline", daemon=True).start()
