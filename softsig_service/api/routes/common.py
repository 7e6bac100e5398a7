"""What the route modules share: problem responses for the OpenAPI document, links and pagination."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Query

from softsig_service.api.deps import WriteAccess
from softsig_service.api.problems import PROBLEM_MEDIA_TYPE
from softsig_service.api.schemas import JobOut, Problem


def problem(description: str) -> dict[str, Any]:
    """An OpenAPI response entry of a problem body."""
    return {"model": Problem, "description": description, "content": {PROBLEM_MEDIA_TYPE: {}}}


COMMON: dict[int | str, dict[str, Any]] = {
    "4XX": problem("a problem with the request (RFC 9457 problem details naming the field)"),
    "5XX": problem("the service could not do it (503: busy or unavailable; retry later)"),
}
READ: dict[int | str, dict[str, Any]] = {401: problem("an API key is required (read_auth is on)"), **COMMON}
WRITE: dict[int | str, dict[str, Any]] = {
    401: problem("missing or unknown X-API-Key"),
    413: problem("request body too large"),
    422: problem("invalid request: the offending field is named"),
    **COMMON,
}

SUBMIT_JOB: dict[str, Any] = {
    "status_code": 202,
    "response_model": JobOut,
    "dependencies": [WriteAccess],
    "responses": {
        501: problem("this job kind is not offered"),
        503: problem("the job queue is full (Retry-After)"),
        **WRITE,
    },
}
"""What every route that submits a job declares: 202 with the job, write access, 501 and 503."""

DEFAULT_LIMIT = 50
"""The page size of every list when ``limit`` is not given."""
Limit = Annotated[int, Query(ge=1, le=500, description="page size (default 50 on every list)")]
Offset = Annotated[int, Query(ge=0, le=10_000_000, description="items to skip")]


def page(items: list[Any], limit: int, offset: int) -> dict[str, Any]:
    """One page of an in-memory list: ``{"items", "total", "limit", "offset"}``."""
    return {"items": items[offset : offset + limit], "total": len(items), "limit": limit, "offset": offset}
