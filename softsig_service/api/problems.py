"""The one place that maps errors onto HTTP: RFC 9457 ``application/problem+json`` bodies.

Every error response of the service is a problem::

    {"type": "urn:softsig:problem:invalid-input", "title": "Invalid input", "status": 422,
     "detail": "must be within [0.0, 0.5] m", "instance": "/v1/plans", "field": "approach_distance",
     "value": 3.0, "choices": null, "request_id": "..."}

``field`` is the dotted path of the offending value inside the request (``object.size[2]``, ``manifest.name``;
for query, path and header parameters their name, e.g. ``limit``, ``hand``, ``If-Match``); validation problems
list every error in ``errors``. Statuses:

====================================  ======  =================================
error                                 status  type slug
====================================  ======  =================================
malformed JSON                        400     malformed-json
Unauthorized (X-API-Key)              401     unauthorized
HandNotFound, NotFound (in the path)  404     not-found
Conflict                              409     conflict
PreconditionFailed (If-Match)         412     precondition-failed
request body over the limit           413     content-too-large
ModelTooLarge                         413     model-too-large
UnsupportedMediaType                  415     unsupported-media-type
request validation (pydantic)         422     validation-error
InvalidInput, InvalidManifest, ...    422     <error name in kebab case>
PreconditionRequired                  428     precondition-required
ServiceBusy                           503     service-busy (Retry-After)
RenderUnavailable                     503     render-unavailable
anything unexpected                   500     internal-error (a bug: never from bad input)
====================================  ======  =================================
"""

from __future__ import annotations

import json
import logging
import re
from collections.abc import Iterable, Mapping
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match, Route
from starlette.types import Receive, Scope, Send

from softsig_service.errors import (
    ServiceBusy,
    SoftsigError,
    Unauthorized,
)
from softsig_service.objects.schema import UNION_TAGS
from softsig_service.services.observability import request_id_var
from softsig_service.services.problems import (
    PROBLEM_MEDIA_TYPE,
    TITLES,
    problem_body,
    short_value,
    slug_of,
    softsig_problem,
)
from softsig_service.validation import error_choices, field_path


class ProblemResponse(JSONResponse):
    """A problem body as ASCII JSON: a value echoed from the request may hold any code point, lone surrogates
    included (they cannot be encoded as UTF-8, but ``\\udc80`` is valid JSON)."""

    media_type = PROBLEM_MEDIA_TYPE

    def render(self, content: Any) -> bytes:
        """The body as compact ASCII JSON."""
        return json.dumps(content, ensure_ascii=True, allow_nan=False, separators=(",", ":")).encode("ascii")


def problem_response(status: int, body: dict[str, Any], headers: dict[str, str] | None = None) -> JSONResponse:
    """A JSONResponse with the problem media type."""
    return ProblemResponse(body, status_code=status, headers=headers)


log = logging.getLogger("softsig.api")


async def _softsig_handler(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, SoftsigError)
    status, body = softsig_problem(exc, request.url.path)
    headers: dict[str, str] = {}
    if isinstance(exc, Unauthorized):
        headers["WWW-Authenticate"] = 'ApiKey header="X-API-Key"'
    if isinstance(exc, ServiceBusy):
        headers["Retry-After"] = "5"
    return problem_response(status, body, headers)


async def _validation_handler(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    errors = list(exc.errors())
    if any(e.get("type") == "json_invalid" for e in errors):
        e = next(e for e in errors if e.get("type") == "json_invalid")
        detail = f"the body is not valid JSON: {(e.get('ctx') or {}).get('error', 'decode error')}"
        pos = e.get("loc", (None, None))[-1]
        body = problem_body(400, slug="malformed-json", detail=detail, instance=request.url.path, field="$",
                            value={"position": pos} if isinstance(pos, int) else None)  # fmt: skip
        return problem_response(400, body)
    items = []
    for e in errors:
        where, path = field_path(tuple(e.get("loc", ())), UNION_TAGS)
        if e.get("type") in ("union_tag_invalid", "union_tag_not_found"):
            tag = str((e.get("ctx") or {}).get("discriminator", "")).strip("'\"")
            if tag:  # the offending field is the discriminator itself
                path = tag if path == "$" else f"{path}.{tag}"
        item: dict[str, Any] = {"field": path, "location": where, "message": e.get("msg", ""), "type": e.get("type")}
        if e.get("type") != "missing":
            item["value"] = short_value(e.get("input"))
        choices = error_choices(e)
        if choices:
            item["choices"] = choices
        items.append(item)
    first = items[0] if items else {"field": "$", "message": "invalid request"}
    body = problem_body(
        422,
        slug="validation-error",
        title="Validation error",
        detail=f"{first['field']}: {first['message']}" + (f" (and {len(items) - 1} more)" if len(items) > 1 else ""),
        instance=request.url.path,
        field=first["field"],
        value=first.get("value"),
        choices=first.get("choices"),
        errors=items,
    )
    return problem_response(422, body)


async def _http_handler(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    status = exc.status_code
    detail = exc.detail if isinstance(exc.detail, str) else None
    slug = "content-too-large" if status == 413 else slug_of(TITLES.get(status, "error").title().replace(" ", ""))
    extra = getattr(exc, "problem_extensions", {})
    headers = dict(exc.headers or {})
    if status == 405:
        # the router names only the first route whose path matched; the resource has the methods of all of them
        own = [r for r in request.app.router.routes if isinstance(r, Route)]  # /openapi.json, /docs, ...
        allowed = allowed_methods([*getattr(request.app.state, "routes", ()), *own], request.scope)
        headers["Allow"] = ", ".join(allowed)
        extra = {**extra, "choices": allowed}
    body = problem_body(status, slug=slug, detail=detail, instance=request.url.path, **extra)
    return problem_response(status, body, headers)


def allowed_methods(routes: Iterable[Any], scope: Mapping[str, Any]) -> list[str]:
    """The methods of the resource at the path of ``scope``: of every route among ``routes`` whose template matches
    it with the fewest parameters (``/v1/hands/archive`` is the archive route's resource, not a hand's), sorted."""
    by_parameters: dict[int, set[str]] = {}
    for route in routes:
        match, child = route.matches(scope)
        if match is not Match.NONE:
            n = len(child.get("path_params", {}))
            by_parameters.setdefault(n, set()).update(getattr(route, "methods", None) or ())
    return sorted(by_parameters[min(by_parameters)]) if by_parameters else []


def internal_error(method: str, path: str, exc: BaseException) -> JSONResponse:
    """The 500 answer to an unexpected error, its traceback logged first; both carry the request's id (call it
    where the id is still set: :class:`~softsig_service.api.logging.RequestContextMiddleware`)."""
    log.error("unhandled error serving %s %s", method, path, exc_info=exc, extra={"request_id": request_id_var.get()})
    body = problem_body(
        500,
        slug="internal-error",
        detail="an unexpected error occurred; the request id identifies it in the service's log",
        instance=path,
    )
    return problem_response(500, body)


async def _unhandled_handler(request: Request, exc: Exception) -> JSONResponse:
    return internal_error(request.method, request.url.path, exc)


def install_problem_handlers(app: FastAPI) -> None:
    """Register the handlers that turn every error into a problem response."""
    app.add_exception_handler(SoftsigError, _softsig_handler)
    app.add_exception_handler(RequestValidationError, _validation_handler)
    app.add_exception_handler(StarletteHTTPException, _http_handler)
    app.add_exception_handler(Exception, _unhandled_handler)


class BodyTooLarge(StarletteHTTPException):
    """The request body exceeded its limit (raised while it is being read)."""

    def __init__(self, limit: int, received: int | None = None) -> None:
        super().__init__(413, detail=f"the request body exceeds the limit of {limit} bytes")
        self.problem_extensions: dict[str, Any] = {"field": "body", "value": received, "limit": limit}


def _limit_for(path: str, methods_upload: tuple[str, ...]) -> bool:
    return any(re.fullmatch(p, path) for p in methods_upload)


class HttpMiddleware:
    """A pure ASGI middleware that acts on HTTP requests only: other scopes (lifespan, websockets) go to ``app``
    untouched; a subclass answers or forwards HTTP requests in :meth:`handle`."""

    app: Any

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        await self.handle(scope, receive, send, scope.get("path", ""))

    async def handle(self, scope: Scope, receive: Receive, send: Send, path: str) -> None:
        """Answer or forward the HTTP request to ``path``."""
        raise NotImplementedError


class BodyLimitMiddleware(HttpMiddleware):
    """Pure ASGI middleware: 413 problem when a request body exceeds its limit.

    The limit is the one of the first of ``route_limits`` (regular expression, bytes) whose pattern matches the
    path, else ``max_upload_bytes`` for a ``multipart/form-data`` body to a path matching one of ``upload_paths``
    (regular expressions; the routes that take uploads) and ``max_body_bytes`` for every other body. A
    ``Content-Length`` over the limit is refused before any byte is read; a body streamed without (or beyond)
    its ``Content-Length`` is counted as it arrives and refused as soon as it passes the limit.
    """

    def __init__(
        self,
        app: Any,
        *,
        max_body_bytes: int,
        max_upload_bytes: int,
        upload_paths: tuple[str, ...],
        route_limits: tuple[tuple[str, int], ...] = (),
    ) -> None:
        self.app = app
        self.max_body = max_body_bytes
        self.max_upload = max_upload_bytes
        self.upload_paths = upload_paths
        self.route_limits = route_limits

    def limit(self, path: str, multipart: bool = True) -> int:
        """The body limit of ``path``: its own (``route_limits``), the upload limit (a ``multipart`` body) or the
        general one."""
        for pattern, limit in self.route_limits:
            if re.fullmatch(pattern, path):
                return limit
        return self.max_upload if multipart and _limit_for(path, self.upload_paths) else self.max_body

    async def handle(self, scope: Scope, receive: Receive, send: Send, path: str) -> None:
        headers = scope.get("headers", ())
        media = next((v for k, v in headers if k == b"content-type"), b"").split(b";", 1)[0].strip().lower()
        limit = self.limit(path, multipart=media == b"multipart/form-data")
        declared: int | None = None
        for key, value in headers:
            if key == b"content-length":
                try:
                    declared = int(value)
                except ValueError:
                    body = problem_body(400, slug="bad-request", detail="Content-Length is not an integer",
                                        instance=path, field="Content-Length")  # fmt: skip
                    await problem_response(400, body)(scope, receive, send)
                    return
                break
        if declared is not None and declared > limit:
            exc = BodyTooLarge(limit, declared)
            body = problem_body(413, slug="content-too-large", detail=str(exc.detail), instance=path,
                                **exc.problem_extensions)  # fmt: skip
            await problem_response(413, body, {"Connection": "close"})(scope, receive, send)
            return
        received = 0

        async def counting_receive() -> Any:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise BodyTooLarge(limit, received)
            return message

        await run_answering(self.app, scope, counting_receive, send, BodyTooLarge, "content-too-large")


async def run_answering(
    app: Any, scope: Scope, receive: Receive, send: Send, error: type[StarletteHTTPException], slug: str
) -> None:
    """Run ``app``; an ``error`` raised by ``receive`` before the response started becomes its problem answer
    (the connection closed), one raised after it is re-raised."""
    started = False

    async def tracking_send(message: Any) -> None:
        nonlocal started
        if message["type"] == "http.response.start":
            started = True
        await send(message)

    try:
        await app(scope, receive, tracking_send)
    except error as exc:
        if started:
            raise
        extensions = getattr(exc, "problem_extensions", {})
        body = problem_body(exc.status_code, slug=slug, detail=str(exc.detail), instance=scope.get("path", ""),
                            **extensions)  # fmt: skip
        await problem_response(exc.status_code, body, {"Connection": "close"})(scope, receive, send)
