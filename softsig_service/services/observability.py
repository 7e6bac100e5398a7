"""What the service observes of itself: the id of the request being served (a context variable, so that log
lines and problem bodies written while serving it carry it, in threads too) and the Prometheus metrics of one app.

Metrics: ``softsig_http_requests_total{method, route, status}``, ``softsig_http_request_duration_seconds{method,
route}`` (histogram, [s]), ``softsig_http_requests_in_progress``, ``softsig_plan_seconds{strategy}`` (planner
time [s]), ``softsig_jobs_running`` and ``softsig_jobs_finished_total{kind, status}``.

Several service processes (``softsig serve --workers N``) count together: when ``PROMETHEUS_MULTIPROC_DIR`` names a
folder (prometheus_client's multiprocess mode; ``softsig serve`` sets one up for its workers), every process
writes its values there and :meth:`Metrics.exposition` sums all of them, whichever process answers the scrape. The
gauges then add the live processes' values.
"""

from __future__ import annotations

import os
from contextvars import ContextVar

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest, multiprocess

request_id_var: ContextVar[str | None] = ContextVar("softsig_request_id", default=None)
"""The id of the request being served (None outside a request)."""


class Metrics:
    """The Prometheus metrics of one app (their own registry)."""

    def __init__(self) -> None:
        self.multiprocess_dir = os.environ.get("PROMETHEUS_MULTIPROC_DIR") or None
        """The folder the processes of one service share their values in (None: this process alone)."""
        self.registry = CollectorRegistry(auto_describe=True)
        self.requests = Counter(
            "softsig_http_requests", "HTTP requests served", ["method", "route", "status"], registry=self.registry
        )
        self.latency = Histogram(
            "softsig_http_request_duration_seconds",
            "HTTP request latency [s] from the first byte received to the last byte sent",
            ["method", "route"],
            buckets=(0.001, 0.002, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0),
            registry=self.registry,
        )
        self.in_progress = self._live_gauge("softsig_http_requests_in_progress", "requests being served")
        self.plan_seconds = Histogram(
            "softsig_plan_seconds",
            "planner wall time per plan [s]",
            ["strategy"],
            buckets=(0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.5, 2.0),
            registry=self.registry,
        )
        self.jobs_running = self._live_gauge("softsig_jobs_running", "jobs running in worker processes")
        self.jobs_finished = Counter(
            "softsig_jobs_finished", "jobs that reached a final status", ["kind", "status"], registry=self.registry
        )

    def _live_gauge(self, name: str, documentation: str) -> Gauge:
        """A gauge of this registry that, with several processes, adds the values of the live ones."""
        return Gauge(name, documentation, registry=self.registry, multiprocess_mode="livesum")

    def exposition(self) -> bytes:
        """The metrics in Prometheus' text format: of every process of the service in multiprocess mode, else of
        this one."""
        if self.multiprocess_dir is None:
            return bytes(generate_latest(self.registry))
        registry = CollectorRegistry()
        multiprocess.MultiProcessCollector(registry, path=self.multiprocess_dir)
        return bytes(generate_latest(registry))

    def process_exited(self) -> None:
        """Drop this process's live gauges from the shared folder (at a graceful exit; multiprocess mode only)."""
        if self.multiprocess_dir is not None:
            multiprocess.mark_process_dead(os.getpid(), self.multiprocess_dir)
