"""How uvicorn serves the app: its configuration, and a header deadline for slow clients.

uvicorn closes a keep-alive connection that stays idle between requests (``timeout_keep_alive``), but once a
client has sent one byte of a request it waits for the rest of the headers for ever: a client trickling one byte
every few seconds holds a connection (and its memory) as long as it likes. :class:`HeaderDeadlineProtocol` gives
every request ``header_timeout`` seconds, counted from the connection's opening or the end of the previous answer
on it, to complete its headers; past that it answers ``408 Request Timeout`` and closes the connection. The body
has its own deadlines (:mod:`softsig_service.api.guard`).
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import uvicorn
from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

_LOG = logging.getLogger("softsig.serving")

DEFAULT_HEADER_TIMEOUT = 10.0  # [s], when the configuration names none
_TIMEOUT_TEXT = b"the request's headers did not arrive in due time\n"
_TIMEOUT_ANSWER = (
    b"HTTP/1.1 408 Request Timeout\r\ncontent-type: text/plain; charset=utf-8\r\n"
    b"content-length: %d\r\nconnection: close\r\n\r\n%s" % (len(_TIMEOUT_TEXT), _TIMEOUT_TEXT)
)


class ServiceConfig(uvicorn.Config):
    """uvicorn's configuration with the service's ``header_timeout`` [s]; it travels with the configuration into
    every worker process of ``softsig serve --workers N``."""

    def __init__(self, app: Any, *, header_timeout: float = DEFAULT_HEADER_TIMEOUT, **kwargs: Any) -> None:
        super().__init__(app, http=HeaderDeadlineProtocol, **kwargs)
        self.header_timeout = header_timeout


class HeaderDeadlineProtocol(HttpToolsProtocol):
    """uvicorn's httptools protocol that answers 408 and closes a connection whose request headers are not complete
    within ``header_timeout`` seconds of the connection's opening or of the end of its previous answer."""

    def __init__(self, config: uvicorn.Config, *args: Any, **kwargs: Any) -> None:
        super().__init__(config, *args, **kwargs)
        self.header_timeout = float(getattr(config, "header_timeout", DEFAULT_HEADER_TIMEOUT))
        self._header_timer: asyncio.TimerHandle | None = None
        self._reading_message = False  # between a request's first byte and its body's end
        self._completed = 0  # requests read whole on this connection
        self._answered = 0  # requests answered on it

    def _arm(self) -> None:
        self._disarm()
        self._header_timer = self.loop.call_later(self.header_timeout, self._headers_overdue)

    def _disarm(self) -> None:
        if self._header_timer is not None:
            self._header_timer.cancel()
            self._header_timer = None

    def _headers_overdue(self) -> None:
        self._header_timer = None
        if self.transport.is_closing():
            return
        client = f"{self.client[0]}:{self.client[1]}" if self.client else None
        _LOG.info("closing a connection whose request headers took longer than %g s", self.header_timeout,
                  extra={"client": client})  # fmt: skip
        self.transport.write(_TIMEOUT_ANSWER)
        self.transport.close()

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._arm()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def on_message_begin(self) -> None:
        self._reading_message = True
        if self._header_timer is None:  # a pipelined request's headers are due too, from their first byte
            self._arm()
        super().on_message_begin()

    def on_headers_complete(self) -> None:
        self._disarm()
        super().on_headers_complete()

    def on_message_complete(self) -> None:
        self._reading_message = False
        self._completed += 1
        super().on_message_complete()
        self._next_headers_due()

    def on_response_complete(self) -> None:
        self._answered += 1
        if self._completed < self._answered and not self.transport.is_closing():
            # answered before its body arrived (a 401 or 404 that never read it): the rest of the body is not
            # waited for, byte by byte, with no deadline; the connection closes after the answer
            super().on_response_complete()
            self.transport.close()
            return
        super().on_response_complete()
        self._next_headers_due()

    def _next_headers_due(self) -> None:
        """Once a request has been read whole and answered, the next one's headers are due (the keep-alive timeout
        closes the connection first if it stays idle)."""
        answered = self.cycle is None or self.cycle.response_complete
        if answered and not self._reading_message and not self.pipeline and not self.transport.is_closing():
            self._arm()
