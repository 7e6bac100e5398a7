"""JSON answers made once and kept: the bytes FastAPI would send for a route's response model, cached per process
under the key of what they were made from.

FastAPI validates an endpoint's return value against its ``response_model`` and serialises it
(``TypeAdapter.dump_json``, by alias) on every request. For a record that has not changed since, that is the same
work for the same bytes. :func:`model_json` does FastAPI's validation and serialisation once (the same
``TypeAdapter`` calls, so the same bytes), and :class:`AnswerCache` keeps them under a key that names the record's
content, read from the database on every request (a hand's :func:`~softsig_service.registry.hand_stamp`, a plan's
id and storage time): a change made by any process of the service changes the key, so a process never answers
from a stale entry. The cache is bounded in bytes (least recently used out first).
"""

from __future__ import annotations

import functools
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable, Mapping
from typing import Any

from fastapi import Response
from pydantic import BaseModel, TypeAdapter

JSON = "application/json"


@functools.cache
def _adapter(model: type[BaseModel]) -> TypeAdapter[Any]:
    return TypeAdapter(model)


def model_json(model: type[BaseModel], content: Any) -> bytes:
    """``content`` validated as ``model`` and serialised as FastAPI serialises a route's response model (a
    validation error raises ``pydantic.ValidationError``, a bug in the service, as FastAPI's would)."""
    adapter = _adapter(model)
    return adapter.dump_json(adapter.validate_python(content), by_alias=True)


def json_response(body: bytes, status_code: int = 200, headers: Mapping[str, str] | None = None) -> Response:
    """A response with the JSON ``body`` as it is."""
    return Response(body, status_code=status_code, headers=dict(headers or {}), media_type=JSON)


Answer = tuple[str, bytes]
"""A kept answer: its ETag ("" for none) and its JSON body."""


class AnswerCache:
    """Answers (:data:`Answer`) by key, at most ``max_bytes`` of bodies together (a body over a quarter of that is
    made every time, not kept); thread-safe (routes run in the thread pool)."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self.bytes = 0
        self._items: OrderedDict[Hashable, Answer] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: Hashable, make: Callable[[], tuple[Hashable, Answer]]) -> Answer:
        """The answer under ``key``; else ``make()``'s ``(key, answer)``, kept under the key it returns (the record
        it read may be newer than ``key``) and returned."""
        with self._lock:
            kept = self._items.get(key)
            if kept is not None:
                self._items.move_to_end(key)
                return kept
        made_key, answer = make()
        if 4 * len(answer[1]) > self.max_bytes:
            return answer
        with self._lock:
            old = self._items.pop(made_key, None)
            self.bytes += len(answer[1]) - (len(old[1]) if old is not None else 0)
            self._items[made_key] = answer
            while self.bytes > self.max_bytes:
                self.bytes -= len(self._items.popitem(last=False)[1][1])
        return answer

    def __len__(self) -> int:
        return len(self._items)
