"""RFC 9457 problem details of softsig's errors: the status, type, title and fields of a
:class:`~softsig_service.errors.SoftsigError` as a JSON object (the HTTP mapping itself is in the API).
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

from softsig_service.errors import (
    Conflict,
    HandNotFound,
    ModelTooLarge,
    NotAvailable,
    NotFound,
    PreconditionFailed,
    PreconditionRequired,
    RenderUnavailable,
    ServiceBusy,
    SoftsigError,
    TimeLimitExceeded,
    Unauthorized,
    UnsupportedMediaType,
)
from softsig_service.services.observability import request_id_var
from softsig_service.services.serialize import to_jsonable

PROBLEM_MEDIA_TYPE = "application/problem+json"
TYPE_PREFIX = "urn:softsig:problem:"

_STATUS: tuple[tuple[type[SoftsigError], int], ...] = (
    (Unauthorized, 401),
    (HandNotFound, 404),
    (NotFound, 404),
    (Conflict, 409),
    (PreconditionFailed, 412),
    (ModelTooLarge, 413),
    (UnsupportedMediaType, 415),
    (PreconditionRequired, 428),
    (NotAvailable, 501),
    (ServiceBusy, 503),
    (RenderUnavailable, 503),
    (TimeLimitExceeded, 422),
)
TITLES = {
    400: "Bad request",
    401: "Unauthorized",
    403: "Forbidden",
    404: "Not found",
    405: "Method not allowed",
    406: "Not acceptable",
    408: "Request timeout",
    409: "Conflict",
    412: "Precondition failed",
    413: "Content too large",
    415: "Unsupported media type",
    422: "Unprocessable content",
    428: "Precondition required",
    429: "Too many requests",
    500: "Internal error",
    501: "Not implemented",
    503: "Service unavailable",
}
_MAX_VALUE_CHARS = 300


def status_of(exc: SoftsigError) -> int:
    """HTTP status of a :class:`SoftsigError` (422 for bad input not listed otherwise)."""
    for cls, status in _STATUS:
        if isinstance(exc, cls):
            return status
    return 422


def slug_of(name: str) -> str:
    """``ServiceBusy`` -> ``service-busy``: the kebab-case type slug of an error class name."""
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
        "title": title or TITLES.get(status, "Error"),
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


def softsig_problem(exc: SoftsigError, instance: str | None = None) -> tuple[int, dict[str, Any]]:
    """Status and problem body of a :class:`SoftsigError`."""
    status = status_of(exc)
    name = type(exc).__name__
    body = problem_body(
        status,
        slug=slug_of(name),
        title=re.sub(r"(?<!^)(?=[A-Z])", " ", name).capitalize(),
        detail=exc.message,
        instance=instance,
        field=exc.field,
        value=short_value(exc.value),
        choices=exc.choices,
    )
    return status, body
