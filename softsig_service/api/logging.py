"""Observability of the service: JSON logs carrying a request id, and Prometheus metrics by route template.

* Every request gets an id: the client's ``X-Request-ID`` when it is a short token (1-128 characters of
  ``A-Za-z0-9._:-``), else a fresh UUID. It is echoed in the ``X-Request-ID`` response header, set in a context
  variable for the duration of the request (so every log line written while serving it carries it, in threads
  too), and put into problem bodies.
* Logs are one JSON object per line on stderr: ``ts`` (UTC, ISO 8601), ``level``, ``logger``, ``message``,
  ``request_id`` and the record's extra fields (``method``, ``path``, ``route``, ``status``, ``duration_ms`` for
  the access log line ``softsig.access``).
* Metrics (a registry per app, so several apps in one process do not collide):
  ``softsig_http_requests_total{method, route, status}``, ``softsig_http_request_duration_seconds{method, route}``
  (histogram), ``softsig_http_requests_in_progress``, ``softsig_plan_seconds{strategy}`` (planner time),
  ``softsig_jobs_running`` and ``softsig_jobs_finished_total{kind, status}``. ``route`` is the route template
  (``/v1/plans/{plan_id}``), never the raw path, or ``unmatched``.
"""

from __future__ import annotations

import json
import logging
import re
import sys
import time
import uuid
from collections.abc import Sequence
from datetime import UTC, datetime
from typing import Any

from starlette.routing import BaseRoute, Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from softsig_service.api.problems import internal_error
from softsig_service.services.observability import Metrics, request_id_var

_REQUEST_ID = re.compile(r"^[A-Za-z0-9._:\-]{1,128}$")
_STANDARD_ATTRS = frozenset(vars(logging.LogRecord("", 0, "", 0, "", None, None))) | {
    "message",
    "asctime",
    "color_message",  # uvicorn's coloured copy of the message
}
access_log = logging.getLogger("softsig.access")


class JsonFormatter(logging.Formatter):
    """One JSON object per record: ts, level, logger, message, request_id, extras, exception."""

    def format(self, record: logging.LogRecord) -> str:
        out: dict[str, Any] = {
            "ts": datetime.fromtimestamp(record.created, UTC).isoformat(timespec="milliseconds"),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        rid = getattr(record, "request_id", None) or request_id_var.get()
        if rid is not None:
            out["request_id"] = rid
        for key, value in record.__dict__.items():
            if key not in _STANDARD_ATTRS and key not in out and not key.startswith("_"):
                out[key] = value
        if record.exc_info:
            out["exception"] = self.formatException(record.exc_info)
        return json.dumps(out, default=str)


def configure_logging(level: str = "info") -> None:
    """Send every log record (softsig's, uvicorn's) to stderr as JSON lines at ``level``."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(JsonFormatter())
    root = logging.getLogger()
    for h in list(root.handlers):
        root.removeHandler(h)
    root.addHandler(handler)
    root.setLevel(level.upper())
    for name in ("uvicorn", "uvicorn.error", "uvicorn.access"):
        lg = logging.getLogger(name)
        lg.handlers.clear()
        lg.propagate = True


def route_template(routes: Sequence[BaseRoute], scope: Scope) -> str:
    """The template of the route that served (or would serve) ``scope``, or ``"unmatched"``."""
    route = scope.get("route")
    path = getattr(route, "path", None)
    if isinstance(path, str):
        return path
    for r in routes:
        try:
            match, _ = r.matches(scope)
        except Exception:
            continue
        if match == Match.FULL:
            return str(getattr(r, "path", "unmatched"))
    return "unmatched"


class RequestContextMiddleware:
    """Pure ASGI middleware: request id in and out, access log line, request metrics by route template."""

    def __init__(self, app: ASGIApp, metrics: Metrics, routes: Sequence[BaseRoute]) -> None:
        self.app = app
        self.metrics = metrics
        self.routes = list(routes)
        # the labelled children by (method, route, status) and (method, route): ``labels()`` takes a lock and
        # checks its labels on every call
        self._counts: dict[tuple[str, str, str], Any] = {}
        self._latencies: dict[tuple[str, str], Any] = {}

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        rid = None
        for key, value in scope.get("headers", ()):
            if key == b"x-request-id":
                text = value.decode("latin-1")
                rid = text if _REQUEST_ID.match(text) else None
                break
        rid = rid or uuid.uuid4().hex
        token = request_id_var.set(rid)
        status = 500
        t0 = time.perf_counter()
        self.metrics.in_progress.inc()

        started = False

        async def send_with_id(message: Message) -> None:
            nonlocal status, started
            if message["type"] == "http.response.start":
                started = True
                status = int(message["status"])
                headers = list(message.get("headers", []))
                headers.append((b"x-request-id", rid.encode("latin-1")))
                message = {**message, "headers": headers}
            await send(message)

        try:
            try:
                await self.app(scope, receive, send_with_id)
            except Exception as exc:  # answered and logged here, where the request's id is still known
                if started:
                    raise
                response = internal_error(scope.get("method", ""), scope.get("path", ""), exc)
                await response(scope, receive, send_with_id)
        finally:
            dt = time.perf_counter() - t0
            self.metrics.in_progress.dec()
            route = route_template(self.routes, scope)
            method = scope.get("method", "")
            key = (method, route, str(status))
            count = self._counts.get(key)
            if count is None:
                count = self._counts[key] = self.metrics.requests.labels(*key)
            count.inc()
            latency = self._latencies.get(key[:2])
            if latency is None:
                latency = self._latencies[key[:2]] = self.metrics.latency.labels(method, route)
            latency.observe(dt)
            if access_log.isEnabledFor(logging.INFO):
                access_log.info(
                    "%s %s %d",
                    method,
                    scope.get("path", ""),
                    status,
                    extra={
                        "method": method,
                        "path": scope.get("path", ""),
                        "route": route,
                        "status": status,
                        "duration_ms": round(dt * 1e3, 3),
                        "request_id": rid,
                    },
                )
            request_id_var.reset(token)
