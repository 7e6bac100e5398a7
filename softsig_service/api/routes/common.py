"""What the route modules share: access and problem responses for the OpenAPI document."""

from __future__ import annotations

from typing import Any, Protocol, TypeVar

from fastapi import Response

from softsig_service.api.deps import ReadAccess, WriteAccess
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

Responses = dict[int | str, dict[str, Any]]
"""The OpenAPI responses of a route by status code (or ``"4XX"`` ranges)."""


def read_route(responses: Responses | None = None) -> dict[str, Any]:
    """The declarations of a route that reads: read access and ``responses`` with the :data:`READ` problems."""
    return {"dependencies": [ReadAccess], "responses": {**(responses or {}), **READ}}


def write_route(responses: Responses | None = None) -> dict[str, Any]:
    """The declarations of a route that writes: write access and ``responses`` with the :data:`WRITE` problems."""
    return {"dependencies": [WriteAccess], "responses": {**(responses or {}), **WRITE}}


SUBMIT_JOB: dict[str, Any] = {
    "status_code": 202,
    "response_model": JobOut,
    **write_route({501: problem("this job kind is not offered"), 503: problem("the job queue is full (Retry-After)")}),
}
"""What every route that submits a job declares: 202 with the job, write access, 501 and 503."""


class _Tagged(Protocol):
    @property
    def etag(self) -> str: ...


T = TypeVar("T", bound=_Tagged)


def with_etag(response: Response, record: T) -> T:
    """``record``, its strong ``ETag`` set on ``response`` (for ``If-Match`` on a later write)."""
    response.headers["ETag"] = record.etag
    return record
