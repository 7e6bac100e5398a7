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
import math
import re
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import Receive, Scope, Send

from softsig_service.api.logging import request_id_var
from softsig_service.api.schemas import UNION_TAGS
from softsig_service.errors import (
    Conflict,
    HandNotFound,
    ModelTooLarge,
    NotFound,
    PreconditionFailed,
    PreconditionRequired,
    RenderUnavailable,
    ServiceBusy,
    SoftsigError,
    TimeLimitExceeded,
    Unauthorized,
)

PROBLEM_MEDIA_TYPE = "application/problem+json"
TYPE_PREFIX = "urn:softsig:problem:"
log = logging.getLogger("softsig.api")

_STATUS: tuple[tuple[type[SoftsigError], int], ...] = (
    (Unauthorized, 401),
    (HandNotFound, 404),
    (NotFound, 404),
    (Conflict, 409),
    (PreconditionFailed, 412),
    (ModelTooLarge, 413),
    (PreconditionRequired, 428),
    (ServiceBusy, 503),
    (RenderUnavailable, 503),
    (TimeLimitExceeded, 422),
)
_TITLES = {
    400: "Bad request",
    401: "Unauthorized",
    403: "Forbidden",
    404: "Not found",
    405: "Method not allowed",
    406: "Not acceptable",
    409: "Conflict",
    412: "Precondition failed",
    413: "Content too large",
    415: "Unsupported media type",
    422: "Unprocessable content",
    428: "Precondition required",
    429: "Too many requests",
    500: "Internal error",
    503: "Service unavailable",
}
_MAX_VALUE_CHARS = 300


def status_of(exc: SoftsigError) -> int:
    """HTTP status of a :class:`SoftsigError` (422 for bad input not listed otherwise)."""
    for cls, status in _STATUS:
        if isinstance(exc, cls):
            return status
    return 422


def _slug(name: str) -> str:
    return re.sub(r"(?<!^)(?=[A-Z])", "-", name).lower()


def short_value(value: Any) -> Any:
    """A JSON-safe, bounded rendering of an offending value (long values become a shortened string)."""
    if value is None or isinstance(value, bool | int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    if isinstance(value, str):
        return value if len(value) <= _MAX_VALUE_CHARS else value[:_MAX_VALUE_CHARS] + "..."
    try:
        from softsig_service.api.schemas import to_jsonable

        plain = to_jsonable(value)
        text = json.dumps(plain)
    except (TypeError, ValueError):
        text = repr(value)
        plain = text
    if len(text) <= _MAX_VALUE_CHARS:
        return plain
    return text[:_MAX_VALUE_CHARS] + "..."


def problem_body(
    status: int,
    *,
    slug: str,
    title: str | None = None,
    detail: str | None = None,
    instance: str | None = None,
    **extensions: Any,
) -> dict[str, Any]:
    """A problem JSON object (extensions with value None are left out, except ``value`` when a field is named)."""
    body: dict[str, Any] = {
        "type": TYPE_PREFIX + slug,
        "title": title or _TITLES.get(status, "Error"),
        "status": status,
    }
    if detail is not None:
        body["detail"] = detail
    if instance is not None:
        body["instance"] = instance
    for key, value in extensions.items():
        if value is not None:
            body[key] = value
    rid = request_id_var.get()
    if rid is not None:
        body["request_id"] = rid
    return body


def problem_response(status: int, body: dict[str, Any], headers: dict[str, str] | None = None) -> JSONResponse:
    """A JSONResponse with the problem media type."""
    return JSONResponse(body, status_code=status, media_type=PROBLEM_MEDIA_TYPE, headers=headers)


def softsig_problem(exc: SoftsigError, instance: str | None = None) -> tuple[int, dict[str, Any]]:
    """Status and problem body of a :class:`SoftsigError`."""
    status = status_of(exc)
    name = type(exc).__name__
    body = problem_body(
        status,
        slug=_slug(name),
        title=re.sub(r"(?<!^)(?=[A-Z])", " ", name).capitalize(),
        detail=exc.message,
        instance=instance,
        field=exc.field,
        value=short_value(exc.value),
        choices=exc.choices,
    )
    return status, body


async def _softsig_handler(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, SoftsigError)
    status, body = softsig_problem(exc, request.url.path)
    headers: dict[str, str] = {}
    if isinstance(exc, Unauthorized):
        headers["WWW-Authenticate"] = 'ApiKey header="X-API-Key"'
    if isinstance(exc, ServiceBusy):
        headers["Retry-After"] = "5"
    return problem_response(status, body, headers)


def field_path(loc: tuple[int | str, ...] | list[int | str]) -> tuple[str, str]:
    """(location, dotted field path) of a pydantic/FastAPI error location.

    ``("body", "object", "box", "size", 2)`` -> ``("body", "object.size[2]")``: the location (body, query, path,
    header) is split off and discriminator tags are left out. The body itself is ``"$"``.
    """
    parts = list(loc)
    where = str(parts.pop(0)) if parts and parts[0] in ("body", "query", "path", "header", "cookie") else "body"
    out = ""
    for k, part in enumerate(parts):
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in UNION_TAGS and (k == 0 or isinstance(parts[k - 1], str)) and k < len(parts) - 1:
            continue
        else:
            out += ("." if out else "") + str(part)
    return where, out or "$"


def _choices(err: dict[str, Any]) -> list[str] | None:
    ctx = err.get("ctx") or {}
    for key in ("expected", "expected_tags"):
        if key in ctx:
            found = re.findall(r"'([^']*)'", str(ctx[key]))
            if found:
                return sorted(found)
    return None


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
        where, path = field_path(tuple(e.get("loc", ())))
        if e.get("type") in ("union_tag_invalid", "union_tag_not_found"):
            tag = str((e.get("ctx") or {}).get("discriminator", "")).strip("'\"")
            if tag:  # the offending field is the discriminator itself
                path = tag if path == "$" else f"{path}.{tag}"
        item: dict[str, Any] = {"field": path, "location": where, "message": e.get("msg", ""), "type": e.get("type")}
        if e.get("type") != "missing":
            item["value"] = short_value(e.get("input"))
        choices = _choices(e)
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
    slug = "content-too-large" if status == 413 else _slug(_TITLES.get(status, "error").title().replace(" ", ""))
    extra = getattr(exc, "problem_extensions", {})
    body = problem_body(status, slug=slug, detail=detail, instance=request.url.path, **extra)
    return problem_response(status, body, dict(exc.headers or {}))


async def _unhandled_handler(request: Request, exc: Exception) -> JSONResponse:
    log.error("unhandled error serving %s %s", request.method, request.url.path, exc_info=exc)
    body = problem_body(
        500,
        slug="internal-error",
        detail="an unexpected error occurred; the request id identifies it in the service's log",
        instance=request.url.path,
    )
    return problem_response(500, body)


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


class BodyLimitMiddleware:
    """Pure ASGI middleware: 413 problem when a request body exceeds its limit.

    The limit is ``max_upload_bytes`` for paths matching one of ``upload_paths`` (regular expressions; the
    multipart routes) and ``max_body_bytes`` for every other path. A ``Content-Length`` over the limit is refused
    before any byte is read; a body streamed without (or beyond) its ``Content-Length`` is counted as it arrives
    and refused as soon as it passes the limit.
    """

    def __init__(self, app: Any, *, max_body_bytes: int, max_upload_bytes: int, upload_paths: tuple[str, ...]) -> None:
        self.app = app
        self.max_body = max_body_bytes
        self.max_upload = max_upload_bytes
        self.upload_paths = upload_paths

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        path = scope.get("path", "")
        limit = self.max_upload if _limit_for(path, self.upload_paths) else self.max_body
        declared: int | None = None
        for key, value in scope.get("headers", ()):
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
        started = False

        async def counting_receive() -> Any:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise BodyTooLarge(limit, received)
            return message

        async def tracking_send(message: Any) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, counting_receive, tracking_send)
        except BodyTooLarge as exc:
            if started:
                raise
            body = problem_body(413, slug="content-too-large", detail=str(exc.detail), instance=path,
                                **exc.problem_extensions)  # fmt: skip
            await problem_response(413, body, {"Connection": "close"})(scope, receive, send)
