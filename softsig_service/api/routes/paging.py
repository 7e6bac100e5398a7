"""Pagination of every list route: ``limit`` and ``offset`` query parameters and one page of a list."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Query

DEFAULT_LIMIT = 50
"""The page size of every list when ``limit`` is not given."""
Limit = Annotated[int, Query(ge=1, le=500, description="page size (default 50 on every list)")]
Offset = Annotated[int, Query(ge=0, le=10_000_000, description="items to skip")]


def page_of(items: list[Any], total: int, limit: int, offset: int) -> dict[str, Any]:
    """A page that was cut already (``items``, of ``total`` in all): ``{"items", "total", "limit", "offset"}``."""
    return {"items": items, "total": total, "limit": limit, "offset": offset}


def page(items: list[Any], limit: int, offset: int) -> dict[str, Any]:
    """One page of an in-memory list: ``{"items", "total", "limit", "offset"}``."""
    return page_of(items[offset : offset + limit], len(items), limit, offset)
