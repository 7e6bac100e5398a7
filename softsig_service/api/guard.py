"""The door of the service, before routing reads a byte of the body: the API key, and a read timeout.

:class:`AuthGateMiddleware` (pure ASGI) answers 401 to a write (``POST``, ``PUT``, ``PATCH``, ``DELETE``) under
``/v1`` without a valid ``X-API-Key``, and to any ``/v1`` request when ``read_auth`` is on, before the body is
received: an unauthenticated 100 MB upload is neither read nor spooled to a temporary file (the connection is
closed after the answer). The route dependencies check the key again, so the OpenAPI document still shows it.

It also bounds how long the service waits for each chunk of a body (``body_read_timeout`` [s]): a client that
sends part of a body and stalls gets 408 (``request-timeout``) and its connection closed.
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
    """No chunk of the request body arrived within the read timeout."""

    def __init__(self, timeout: float) -> None:
        super().__init__(408, detail=f"no part of the request body arrived within {timeout:g} s")
        self.problem_extensions: dict[str, Any] = {"field": "body", "value": timeout}


class AuthGateMiddleware(HttpMiddleware):
    """401 before the body is read when the API key is missing or wrong; 408 when the body stalls."""

    def __init__(self, app: Any, *, api_keys: list[str], read_auth: bool, body_read_timeout: float) -> None:
        self.app = app
        self.keys = api_keys
        self.read_auth = read_auth
        self.timeout = body_read_timeout

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

        async def timed_receive() -> Any:
            nonlocal body_done
            if body_done:  # after the body: waiting for a disconnect is not bounded
                return await receive()
            try:
                message = await asyncio.wait_for(receive(), self.timeout)
            except TimeoutError:
                raise BodyReadTimeout(self.timeout) from None
            body_done = message["type"] != "http.request" or not message.get("more_body", False)
            return message

        await run_answering(self.app, scope, timed_receive, send, BodyReadTimeout, "request-timeout")
