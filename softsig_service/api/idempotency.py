"""``Idempotency-Key`` on the POST routes that create something: a retry gets the first response, not a second
resource.

* A creating POST may carry ``Idempotency-Key`` (1-255 visible ASCII characters). Its scope is the caller (a hash
  of its ``X-API-Key``), the path and the key. The first request is served as usual; if it succeeds (2xx), its
  status, ``Content-Type``, ``Location`` and ``ETag`` and its body are stored for 24 h
  (:mod:`softsig_service.registry.idempotency`, so every process of the service sees them).
* A retry with the same key and the same body gets that response again, with ``Idempotent-Replayed: true``; with
  another body it gets **422** naming ``Idempotency-Key``; while the first is still being served, **409**.
* A first request that does not succeed (4xx, 5xx) is not stored: a retry runs again.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Sequence
from typing import Any

from fastapi.routing import APIRoute
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import Headers
from starlette.routing import BaseRoute
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from softsig_service.api.problems import problem_body, problem_response
from softsig_service.registry.idempotency import claim_key, complete_key, find_key, release_key

HEADER = "idempotency-key"
KEY_PATTERN = re.compile(r"^[\x21-\x7e]{1,255}$")
CREATING_STATUSES = (201, 202)
"""A POST route that answers one of these creates something (a hand, a signature version, a stored plan, a job,
a cancellation request)."""
KEPT_HEADERS = (b"content-type", b"location", b"etag")


def creating_routes(routes: Sequence[BaseRoute]) -> list[APIRoute]:
    """The POST routes among ``routes`` that declare a creating answer (:data:`CREATING_STATUSES`), as their
    status code or among their documented responses: the routes ``Idempotency-Key`` covers."""
    out = []
    for route in routes:
        if isinstance(route, APIRoute) and "POST" in (route.methods or ()):
            declared = {route.status_code, *(int(code) for code in route.responses if str(code).isdigit())}
            if declared & set(CREATING_STATUSES):
                out.append(route)
    return out


class IdempotencyMiddleware:
    """Pure ASGI middleware implementing ``Idempotency-Key`` (module docstring) on the app's creating POST routes
    (:func:`creating_routes` of ``routes``)."""

    def __init__(self, app: ASGIApp, routes: Sequence[BaseRoute]) -> None:
        self.app = app
        self.routes = creating_routes(routes)

    def covers(self, path: str) -> bool:
        """Whether ``path`` is served by a creating POST route."""
        return any(route.path_regex.match(path) for route in self.routes)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        headers = Headers(scope=scope) if scope["type"] == "http" and scope.get("method") == "POST" else Headers()
        key = headers.get(HEADER)
        ctx = getattr(scope["app"].state, "ctx", None) if key is not None else None
        if key is None or ctx is None or not self.covers(scope.get("path", "")):
            await self.app(scope, receive, send)
            return
        path = scope["path"]
        if not KEY_PATTERN.fullmatch(key):
            body = problem_body(400, slug="bad-request", detail="Idempotency-Key must be 1-255 visible ASCII "
                                "characters", instance=path, field="Idempotency-Key")  # fmt: skip
            await problem_response(400, body)(scope, receive, send)
            return
        caller = hashlib.sha256(headers.get("x-api-key", "").encode()).hexdigest()
        scope_id = hashlib.sha256(f"{caller}\n{path}\n{key}".encode()).hexdigest()
        registry = ctx.registry
        stored = await run_in_threadpool(find_key, registry, scope_id)
        if stored is not None and stored.status is not None:
            digest = hashlib.sha256()
            while True:
                message = await receive()
                digest.update(message.get("body", b""))
                if not message.get("more_body", False):
                    break
            if digest.hexdigest() != stored.request_hash:
                detail = "this Idempotency-Key was used with another request body"
                body = problem_body(422, slug="invalid-input", title="Invalid input", detail=detail, instance=path,
                                    field="Idempotency-Key")  # fmt: skip
                await problem_response(422, body)(scope, receive, send)
                return
            replayed = [(k.encode("latin-1"), v.encode("latin-1")) for k, v in stored.headers.items()]
            replayed.append((b"idempotent-replayed", b"true"))
            await send({"type": "http.response.start", "status": stored.status, "headers": replayed})
            await send({"type": "http.response.body", "body": stored.body.encode("utf-8")})
            return
        if stored is not None or not await run_in_threadpool(claim_key, registry, scope_id):
            body = problem_body(409, slug="conflict", detail="a request with this Idempotency-Key is in progress",
                                instance=path, field="Idempotency-Key")  # fmt: skip
            await problem_response(409, body, {"Retry-After": "1"})(scope, receive, send)
            return
        await self._first(scope, receive, send, registry, scope_id)

    async def _first(self, scope: Scope, receive: Receive, send: Send, registry: Any, scope_id: str) -> None:
        digest = hashlib.sha256()
        status = 0
        kept: dict[str, str] = {}
        chunks: list[bytes] = []

        async def hashing_receive() -> Message:
            message = await receive()
            if message["type"] == "http.request":
                digest.update(message.get("body", b""))
            return message

        async def capturing_send(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
                for k, v in message.get("headers", ()):
                    if bytes(k).lower() in KEPT_HEADERS:
                        kept[bytes(k).decode("latin-1").lower()] = bytes(v).decode("latin-1")
            elif message["type"] == "http.response.body":
                chunks.append(message.get("body", b""))
            await send(message)

        try:
            await self.app(scope, hashing_receive, capturing_send)
        except BaseException:
            await run_in_threadpool(release_key, registry, scope_id)
            raise
        if 200 <= status < 300:
            await run_in_threadpool(
                lambda: complete_key(registry, scope_id, request_hash=digest.hexdigest(), status=status,
                                     headers=kept, body=b"".join(chunks).decode("utf-8", "replace"))
            )  # fmt: skip
        else:
            await run_in_threadpool(release_key, registry, scope_id)
