"""FastAPI dependencies: the app's context, API-key checks and the If-Match header.

Writes (POST, PUT, DELETE) need ``X-API-Key`` with one of the keys of ``Settings.api_keys``; with no key
configured every write is refused. Reads are open unless ``Settings.read_auth`` is set. Keys are compared in
constant time (:func:`hmac.compare_digest`, every configured key is compared so the time does not depend on which
one matched).
"""

from __future__ import annotations

import hmac
from typing import Annotated

from fastapi import Depends, Header, Request, Security
from fastapi.security import APIKeyHeader

from softsig_service.api.context import AppContext
from softsig_service.errors import PreconditionRequired, Unauthorized

API_KEY_DESCRIPTION = "an API key of the service (SOFTSIG_API_KEYS)"


async def get_ctx(request: Request) -> AppContext:
    """The :class:`~softsig_service.api.app.AppContext` the lifespan made."""
    ctx: AppContext = request.app.state.ctx
    return ctx


Ctx = Annotated[AppContext, Depends(get_ctx)]


def key_is_valid(given: str | None, keys: list[str]) -> bool:
    """Whether ``given`` equals one of ``keys``, comparing all of them in constant time."""
    if not given or not keys:
        return False
    raw = given.encode("utf-8", "surrogateescape")
    ok = False
    for key in keys:
        ok |= hmac.compare_digest(raw, key.encode("utf-8"))
    return ok


class AccessCheck(APIKeyHeader):
    """The ``X-API-Key`` header as the OpenAPI document's security scheme (``APIKeyHeader``) and a route's check of
    it, in one dependency (FastAPI solves one level per request instead of a check depending on the header's
    scheme): with ``write``, a valid key is needed; else only when ``Settings.read_auth`` is set."""

    def __init__(self, *, write: bool) -> None:
        super().__init__(
            name="X-API-Key", auto_error=False, description=API_KEY_DESCRIPTION, scheme_name="APIKeyHeader"
        )
        self.write = write

    async def __call__(self, request: Request) -> None:  # type: ignore[override]
        """:class:`Unauthorized` (naming ``X-API-Key``) when the request may not use the route."""
        ctx: AppContext = request.app.state.ctx
        key = request.headers.get("x-api-key")
        if self.write:
            if not ctx.api_keys:
                raise Unauthorized(
                    "writes are disabled: the service has no API key configured (SOFTSIG_API_KEYS)", field="X-API-Key"
                )
            if not key_is_valid(key, ctx.api_keys):
                raise Unauthorized("a valid X-API-Key header is required for writes", field="X-API-Key")
        elif ctx.settings.read_auth and not key_is_valid(key, ctx.api_keys):
            raise Unauthorized("a valid X-API-Key header is required (read_auth is on)", field="X-API-Key")


WriteAccess = Security(AccessCheck(write=True))
"""Writes need a valid ``X-API-Key``."""
ReadAccess = Security(AccessCheck(write=False))
"""Reads need a valid ``X-API-Key`` only when ``Settings.read_auth`` is set."""


IF_MATCH_REQUIRED_DESCRIPTION = "the ETag of the resource's current representation"
"""The description of the ``If-Match`` header that ``require_if_match`` makes required (the OpenAPI document
marks it so: :mod:`softsig_service.api.contract`)."""


async def if_match_required(
    request: Request,
    if_match: Annotated[str | None, Header(alias="If-Match", description=IF_MATCH_REQUIRED_DESCRIPTION)] = None,
) -> str | None:
    """The ``If-Match`` header of an update or delete; 428 when it is missing and ``require_if_match`` is set."""
    ctx: AppContext = request.app.state.ctx
    if if_match is None and ctx.settings.require_if_match:
        raise PreconditionRequired(
            "this update needs If-Match with the resource's ETag (GET it first)", field="If-Match"
        )
    return if_match


async def if_match_optional(
    if_match: Annotated[
        str | None,
        Header(alias="If-Match", description="optional: the ETag of the hand's latest signature version"),
    ] = None,
) -> str | None:
    """An optional ``If-Match`` header."""
    return if_match


IfMatchRequired = Annotated[str | None, Depends(if_match_required)]
IfMatchOptional = Annotated[str | None, Depends(if_match_optional)]
