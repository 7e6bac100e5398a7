"""What the service observes of itself: the id of the request being served (a context variable, so that log
lines and problem bodies written while serving it carry it, in threads too) and the Prometheus metrics of one app.

Metrics: ``softsig_http_requests_total{method, route, status}``, ``softsig_http_request_duration_seconds{method,
route}`` (histogram, [s]), ``softsig_http_requests_in_progress``, ``softsig_plan_seconds{strategy}`` (planner
time [s]), ``softsig_jobs_running`` and ``softsig_jobs_finished_total{kind, status}``.
"""

from __future__ import annotations

from contextvars import ContextVar

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram

request_id_var: ContextVar[str | None] = ContextVar("softsig_request_id", default=None)
"""The id of the request being served (None outside a request)."""


class Metrics:
    """The Prometheus metrics of one app (their own registry)."""

    def __init__(self) -> None:
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
        self.in_progress = Gauge("softsig_http_requests_in_progress", "requests being served", registry=self.registry)
        self.plan_seconds = Histogram(
            "softsig_plan_seconds",
            "planner wall time per plan [s]",
            ["strategy"],
            buckets=(0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.5, 2.0),
            registry=self.registry,
        )
        self.jobs_running = Gauge("softsig_jobs_running", "jobs running in worker processes", registry=self.registry)
        self.jobs_finished = Counter(
            "softsig_jobs_finished", "jobs that reached a final status", ["kind", "status"], registry=self.registry
        )
