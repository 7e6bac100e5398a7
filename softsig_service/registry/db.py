"""The registry's database: an engine, read and write sessions, and SQLite's settings.

A SQLite file by default (``Settings.resolved_database_url()``: ``<data_dir>/registry.sqlite3``), PostgreSQL when
``SOFTSIG_DATABASE_URL`` names one (``postgresql+psycopg://...``; the driver is an optional extra).

SQLite is set up on every new connection (connection events, not a one-off script):

* ``journal_mode=WAL`` — readers never block the writer and the writer never blocks readers;
* ``foreign_keys=ON`` — deleting a hand deletes its signatures;
* ``busy_timeout`` — a writer waits up to ``busy_timeout`` [s] for another writer instead of failing at once;
* ``synchronous=NORMAL`` — durable across a crash of the process (WAL), one fsync per checkpoint.

Transactions are started by SQLAlchemy, not by the driver (pysqlite's implicit ``BEGIN`` is switched off, as the
SQLAlchemy docs recommend): reads start a deferred ``BEGIN``; write sessions (:meth:`Registry.write`) start
``BEGIN IMMEDIATE``, taking SQLite's write lock up front so that two writers queue on the busy timeout rather than
deadlock on a lock upgrade. The plan path's lone statements (:meth:`Registry.read_core`,
:meth:`Registry.write_core`) run without ``BEGIN``: SQLite wraps a statement outside a transaction in one of its
own, which is atomic and holds no lock between statements, so no upgrade can deadlock either. On SQLite the
writing threads of one process also take turns on a lock of the process (bounded by the same busy timeout, then
:class:`~softsig_service.errors.ServiceBusy`): SQLite's busy handler waits by sleeping 1, 2, 5, 10, ... ms, which
costs concurrent writers of one process tens of milliseconds. On PostgreSQL all are plain transactions;
signature versions are allocated with a row-locking ``UPDATE ... RETURNING`` there as here.

The schema is made and upgraded by Alembic migrations (:mod:`softsig_service.registry.migrate`), in a write
transaction, whenever a :class:`Registry` is opened with ``create=True`` (the service's start).
"""

from __future__ import annotations

import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pydantic_core
from sqlalchemy import Connection, Engine, create_engine, event, text
from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session, sessionmaker

from softsig_service.errors import ServiceBusy
from softsig_service.registry import migrate

_WRITE_OPTION = "softsig_write"
_LONE_OPTION = "softsig_lone_statement"


def _is_sqlite(url: str) -> bool:
    return make_url(url).get_backend_name() == "sqlite"


def json_text(value: Any) -> str:
    """``value`` as the JSON text a JSON column stores: what ``json.dumps`` gives (NaN and Infinity written as
    JavaScript constants, as ``json.dumps`` does), by pydantic-core's serialiser, several times faster on a plan's
    result; without the blanks between items and with non-ASCII characters as they are."""
    return pydantic_core.to_json(value, inf_nan_mode="constants").decode()


def make_engine(url: str, *, busy_timeout: float = 10.0) -> Engine:
    """An engine for ``url``; a SQLite file's folder is created and its connections are configured (see above).
    JSON columns are written by :func:`json_text`."""
    if not _is_sqlite(url):
        return create_engine(url, pool_pre_ping=True, json_serializer=json_text)
    u = make_url(url)
    if u.database and u.database != ":memory:":
        Path(u.database).expanduser().parent.mkdir(parents=True, exist_ok=True)
    engine = create_engine(
        url, connect_args={"check_same_thread": False, "timeout": busy_timeout}, json_serializer=json_text
    )
    timeout_ms = int(busy_timeout * 1000)

    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None  # SQLAlchemy emits BEGIN itself (below)
        cur = dbapi_connection.cursor()
        cur.execute(f"PRAGMA busy_timeout={timeout_ms}")
        # switching a new file to WAL needs it alone, and SQLite answers "locked" at once (no busy wait) while
        # other connections open it, as several workers starting together do: retry until the busy timeout
        deadline = time.monotonic() + busy_timeout
        while True:
            try:
                cur.execute("PRAGMA journal_mode=WAL")
                break
            except sqlite3.OperationalError as exc:
                if "locked" not in str(exc) or time.monotonic() > deadline:
                    raise
                time.sleep(0.01)
        cur.execute("PRAGMA foreign_keys=ON")
        cur.execute("PRAGMA synchronous=NORMAL")
        cur.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn: Any) -> None:
        options = conn.get_execution_options()
        if options.get(_LONE_OPTION, False):
            return  # one statement in autocommit mode: SQLite makes it a transaction of its own
        conn.exec_driver_sql("BEGIN IMMEDIATE" if options.get(_WRITE_OPTION, False) else "BEGIN")

    return engine


class Registry:
    """The database of one service: engine, session factories and schema upgrades.

    ``read()`` gives a session for queries; ``write()`` a session in a write transaction that commits on success
    and rolls back on an exception.
    """

    def __init__(self, url: str, *, busy_timeout: float = 10.0, create: bool = True) -> None:
        self.url = url
        self.engine = make_engine(url, busy_timeout=busy_timeout)
        self.is_sqlite = _is_sqlite(url)
        self.busy_timeout = busy_timeout
        # SQLite's busy handler waits for a held write lock by sleeping 1, 2, 5, 10, ... ms: the threads of one
        # process queue on a lock of their own instead, and only the processes meet at SQLite's
        self._sqlite_writers = threading.RLock() if self.is_sqlite else None
        self._read = sessionmaker(self.engine, expire_on_commit=False)
        self._write_engine = self.engine.execution_options(**{_WRITE_OPTION: True})
        self._write = sessionmaker(self._write_engine, expire_on_commit=False)
        self._lone_engine = self.engine.execution_options(**{_LONE_OPTION: True})
        if create:
            self.upgrade_schema()

    def upgrade_schema(self) -> str:
        """Make or upgrade the schema to the newest revision this code knows (idempotent); returns that revision.

        Raises :class:`~softsig_service.registry.migrate.SchemaTooNew` when the database was written by a newer
        softsig.
        """
        with self._writer(), self._write_engine.begin() as conn:
            return migrate.upgrade(conn)

    @contextmanager
    def read(self) -> Iterator[Session]:
        """A session for reads (its transaction is rolled back at the end)."""
        with self._read() as session:
            yield session

    @contextmanager
    def _writer(self) -> Iterator[None]:
        """On SQLite, this process's turn to write (:class:`ServiceBusy` after ``busy_timeout`` [s] without it);
        elsewhere nothing: the server queues the writers itself."""
        lock = self._sqlite_writers
        if lock is None:
            yield
            return
        if not lock.acquire(timeout=self.busy_timeout):
            raise ServiceBusy("the registry is busy with other writes; retry", field=None)
        try:
            yield
        finally:
            lock.release()

    @contextmanager
    def write(self) -> Iterator[Session]:
        """A session in a write transaction: committed when the block ends, rolled back on an exception."""
        with self._writer(), self._write() as session, session.begin():
            yield session

    @contextmanager
    def read_core(self) -> Iterator[Connection]:
        """A Core connection for one read statement, for the hot paths that need no ORM session. On SQLite the
        statement is its own transaction (no ``BEGIN``/``ROLLBACK`` round trips); elsewhere it runs in one,
        rolled back at the end. Run one statement only: two would not see one snapshot on SQLite."""
        with self._lone_engine.connect() as conn:
            yield conn

    @contextmanager
    def write_core(self) -> Iterator[Connection]:
        """A Core connection for one write statement, in this process's turn to write (:meth:`write`'s). On
        SQLite the statement is its own transaction (atomic, committed when it ends: no ``BEGIN IMMEDIATE`` and
        ``COMMIT`` round trips); elsewhere it runs in one, committed when the block ends and rolled back on an
        exception. Run one statement only, and nothing that may fail after it: on SQLite two statements commit
        one by one, and an exception after the statement does not undo it."""
        with self._writer(), self._lone_engine.connect() as conn:
            yield conn
            conn.commit()

    def ping(self) -> bool:
        """Whether the database answers a trivial query."""
        try:
            with self.engine.connect() as conn:
                conn.execute(text("SELECT 1"))
            return True
        except Exception:
            return False

    def dispose(self) -> None:
        """Close every pooled connection."""
        self.engine.dispose()
