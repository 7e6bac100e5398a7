"""Children die with their parent: a worker process (compute pool, job) that outlives the service would keep
computing and writing into a registry that has moved on.

:func:`follow_parent` starts a daemon thread in the child that checks every ``interval`` seconds whether its
parent is still the process that started it (after the parent dies the child is re-parented, so ``getppid``
changes); then it kills its own process group (a job's process leads one, holding the workers it started) or
only itself, at once, with ``SIGKILL``. A check rather than ``PR_SET_PDEATHSIG``: that signal follows the parent
*thread*, and the service starts its children from pool threads that may end while the child still runs.

:func:`die_with_parent` is for a child started from its parent's main thread (the service processes of
``softsig serve --workers N``, started by uvicorn's supervisor): ``PR_SET_PDEATHSIG`` with ``SIGKILL``, so that
it dies the moment its parent does (a container runtime that kills the supervisor must not leave a worker
answering on the port), plus :func:`follow_parent` where the call is not available.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
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


PR_SET_PDEATHSIG = 1
"""``prctl`` option: the signal this process gets when its parent (thread) dies (Linux)."""


def die_with_parent() -> bool:
    """Get ``SIGKILL`` as soon as the parent dies (``PR_SET_PDEATHSIG``; Linux), and follow it by a check too.
    Returns whether the kernel took the request. Call it from a child started by its parent's main thread."""
    parent = os.getppid()
    armed = False
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    if os.getppid() != parent:  # the parent died before the request took effect
        os.kill(os.getpid(), signal.SIGKILL)
    follow_parent()
    return armed
