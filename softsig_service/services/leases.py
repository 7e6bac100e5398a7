"""The heartbeat of the jobs a process holds: their leases renewed on a thread of its own.

A job's lease (``job_lease`` [s], :mod:`softsig_service.registry.jobs`) must not expire while the process holding it
is alive. The renewals therefore do not wait on the service's event loop, which a burst of requests, a slow hook or
a starved CPU can hold up for seconds, nor on the job's own process: :class:`LeaseKeeper` renews every lease it
holds each ``interval`` [s] from a daemon thread that does nothing else, so a lease is lost only when the whole
process stops being scheduled for longer than ``lease - interval`` (by default 30 s - 10 s), or when the registry
says the job is no longer this process's (another process claimed it after an expiry, it was finished). A renewal
that fails (the database busy or away) is retried at the next beat; it does not count as a lost lease.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

from softsig_service import registry as repo
from softsig_service.registry.db import Registry

log = logging.getLogger("softsig.jobs")


@dataclass
class LeaseState:
    """What the last renewal of one lease found."""

    held: bool = True
    """False once the registry said the job is no longer this owner's (the caller must stop its run)."""
    cancel_requested: bool = False
    """A cancellation was requested in the registry (possibly through another process)."""


class LeaseKeeper:
    """Renews the leases of ``owner`` on the jobs it holds, every ``interval`` [s], by ``lease`` [s] from now."""

    def __init__(self, registry: Registry, owner: str, lease: float, interval: float) -> None:
        self.registry = registry
        self.owner = owner
        self.lease = lease
        self.interval = interval
        self._held: dict[str, LeaseState] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the heartbeat thread (idempotent)."""
        if self._thread is None:
            self._stop.clear()
            self._thread = threading.Thread(target=self._beat, name="softsig-lease-keeper", daemon=True)
            self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the heartbeat thread; the leases it held then expire unless released."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None

    def hold(self, job_id: str) -> None:
        """Keep renewing the lease on ``job_id`` (just claimed by ``owner``)."""
        with self._lock:
            self._held[job_id] = LeaseState()

    def release(self, job_id: str) -> None:
        """Stop renewing the lease on ``job_id`` (its run ended, or was handed back)."""
        with self._lock:
            self._held.pop(job_id, None)

    def state(self, job_id: str) -> LeaseState:
        """What the last renewal of ``job_id`` found (held, as claimed, until a renewal says otherwise)."""
        with self._lock:
            st = self._held.get(job_id)
            return LeaseState(st.held, st.cancel_requested) if st is not None else LeaseState(held=False)

    def renew_all(self) -> None:
        """One beat: renew every lease still held."""
        with self._lock:
            ids = [job_id for job_id, st in self._held.items() if st.held]
        for job_id in ids:
            try:
                rec = repo.renew_lease(self.registry, job_id, self.owner, self.lease)
            except Exception:  # the database busy or away: the lease still runs, try again at the next beat
                log.warning("job %s: renewing its lease failed; retrying in %.3g s", job_id, self.interval)
                continue
            with self._lock:
                st = self._held.get(job_id)
                if st is not None:
                    st.held = rec is not None
                    st.cancel_requested = bool(rec is not None and rec.cancel_requested)

    def _beat(self) -> None:
        while not self._stop.wait(self.interval):
            self.renew_all()
