"""The door of the service, before routing reads a byte of the body: the API key, and a read timeout.

:class:`AuthGateMiddleware` (pure ASGI) answers 401 to a write (``POST``, ``PUT``, ``PATCH``, ``DELETE``) under
``/v1`` without a valid ``X-API-Key``, and to any ``/v1`` request when ``read_auth`` is on, before the body is
received: an unauthenticated 100 MB upload is neither read nor spooled to a temporary file (the connection is
closed after the answer). The route dependencies check the key again, so the OpenAPI document still shows it.

It also bounds how long the service waits for a body: for each chunk (``body_read_timeout`` [s]), so that a client
that sends part of a body and stalls gets 408 (``request-timeout``) and its connection closed, and for the whole
body (``body_deadline`` [s], counted from the first time the app asks for it), so that a client trickling a byte
now and then gets the same. The headers' deadline is the HTTP protocol's (:mod:`softsig_service.api.serving`).
"""

from __future__ import annotations

import asyncio
from typing import Any

from starlette.datastructures import Headers
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import Receive, Scope, Send

from softsig_service.api.deps import key_is_valid
from softsig_service.api.problems import HttpMiddleware, problem_response, run_answering
from softsig_service.services.problems import problem_body

_WRITES = frozenset({"POST", "PUT", "PATCH", "DELETE"})


class BodyReadTimeout(StarletteHTTPException):
    """No chunk of the request body arrived within the read timeout, or the whole body not within its deadline."""

    def __init__(self, timeout: float, *, whole: bool = False) -> None:
        what = "the whole request body did not arrive" if whole else "no part of the request body arrived"
        super().__init__(408, detail=f"{what} within {timeout:g} s")
        self.problem_extensions: dict[str, Any] = {"field": "body", "value": timeout}


class AuthGateMiddleware(HttpMiddleware):
    """401 before the body is read when the API key is missing or wrong; 408 when the body stalls."""

    def __init__(
        self, app: Any, *, api_keys: list[str], read_auth: bool, body_read_timeout: float, body_deadline: float
    ) -> None:
        self.app = app
        self.keys = api_keys
        self.read_auth = read_auth
        self.timeout = body_read_timeout
        self.deadline = body_deadline

    def _refusal(self, scope: Scope) -> str | None:
        """Why the request is refused (the problem's detail), or None."""
        path: str = scope.get("path", "")
        if not path.startswith("/v1/"):
            return None
        write = scope.get("method", "GET") in _WRITES
        if not write and not self.read_auth:
            return None
        given = Headers(scope=scope).get("x-api-key")
        if given is not None and key_is_valid(given, self.keys):
            return None
        if write and not self.keys:
            return "writes are disabled: the service has no API key configured (SOFTSIG_API_KEYS)"
        return "a valid X-API-Key header is required" + (" for writes" if write else " (read_auth is on)")

    async def handle(self, scope: Scope, receive: Receive, send: Send, path: str) -> None:
        refusal = self._refusal(scope)
        if refusal is not None:
            body = problem_body(401, slug="unauthorized", detail=refusal, instance=path, field="X-API-Key")
            headers = {"WWW-Authenticate": 'ApiKey header="X-API-Key"', "Connection": "close"}
            await problem_response(401, body, headers)(scope, receive, send)
            return
        body_done = False
        timed_out = False
        due: float | None = None  # [s, the loop's clock] when the whole body must have arrived

        async def timed_receive() -> Any:
            nonlocal body_done, due, timed_out
            if body_done:  # after the body: waiting for a disconnect is not bounded
                return await receive()
            now = asyncio.get_running_loop().time()
            if due is None:
                due = now + self.deadline
            wait = min(self.timeout, due - now)
            try:
                message = await asyncio.wait_for(receive(), max(wait, 0.0))
            except TimeoutError:
                timed_out = True
                whole = wait < self.timeout
                raise BodyReadTimeout(self.deadline if whole else self.timeout, whole=whole) from None
            body_done = message["type"] != "http.request" or not message.get("more_body", False)
            return message

        async def closing_send(message: Any) -> None:
            # whichever handler answers a timed-out body, the connection closes after it: the rest of the body
            # is not waited for
            if timed_out and message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), (b"connection", b"close")]}
            await send(message)

        await run_answering(self.app, scope, timed_receive, closing_send, BodyReadTimeout, "request-timeout")
