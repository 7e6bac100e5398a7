"""JSON answers made once and kept: the bytes FastAPI would send for a route's response model, cached per process
under the key of what they were made from.

FastAPI validates an endpoint's return value against its ``response_model`` and serialises it
(``TypeAdapter.dump_json``, by alias) on every request. For a record that has not changed since, that is the same
work for the same bytes. :func:`model_json` does FastAPI's validation and serialisation once (the same
``TypeAdapter`` calls, so the same bytes), and :class:`AnswerCache` keeps them under a key that names the record's
content, read from the database on every request (a hand's :func:`~softsig_service.registry.hand_stamp`, a plan's
id and storage time): a change made by any process of the service changes the key, so a process never answers
from a stale entry. The cache is bounded in bytes (least recently used out first).

The routes that answer from it run on the event loop: the key is one indexed row read (tens of microseconds on
SQLite in WAL mode, where a reader never waits for a writer, and one round trip on PostgreSQL), less than the hop
to a worker thread costs; only making an answer (the whole record read and converted) goes to the thread pool.
"""

from __future__ import annotations

import functools
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable, Mapping
from typing import Any

from fastapi import Response
from pydantic import BaseModel, TypeAdapter
from starlette.concurrency import run_in_threadpool

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
        kept = self._kept(key)
        return kept if kept is not None else self._keep(*make())

    async def aget(self, key: Hashable, make: Callable[[], tuple[Hashable, Answer]]) -> Answer:
        """:meth:`get` for a route on the event loop: a kept answer at once, ``make`` (which reads the database)
        in the thread pool."""
        kept = self._kept(key)
        return kept if kept is not None else self._keep(*await run_in_threadpool(make))

    def _kept(self, key: Hashable) -> Answer | None:
        with self._lock:
            kept = self._items.get(key)
            if kept is not None:
                self._items.move_to_end(key)
            return kept

    def _keep(self, key: Hashable, answer: Answer) -> Answer:
        if 4 * len(answer[1]) > self.max_bytes:
            return answer
        with self._lock:
            old = self._items.pop(key, None)
            self.bytes += len(answer[1]) - (len(old[1]) if old is not None else 0)
            self._items[key] = answer
            while self.bytes > self.max_bytes:
                self.bytes -= len(self._items.popitem(last=False)[1][1])
        return answer

    def __len__(self) -> int:
        return len(self._items)
