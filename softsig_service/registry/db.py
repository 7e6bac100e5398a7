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
:meth:`Registry.fetch_one`, :meth:`Registry.write_core`, :meth:`Registry.insert_one`) run without ``BEGIN``: SQLite
wraps a statement outside a transaction in one of its own, which is atomic and holds no lock between statements, so
no upgrade can deadlock either. On SQLite the writing threads of one process also take turns on a lock of the
process (bounded by the same busy timeout, then :class:`~softsig_service.errors.ServiceBusy`): SQLite's busy handler
waits by sleeping 1, 2, 5, 10, ... ms, which costs concurrent writers of one process tens of milliseconds. On
PostgreSQL all are plain transactions; signature versions are allocated with a row-locking ``UPDATE ... RETURNING``
there as here.

The schema is made and upgraded by Alembic migrations (:mod:`softsig_service.registry.migrate`), in a write
transaction, whenever a :class:`Registry` is opened with ``create=True`` (the service's start).
"""

from __future__ import annotations

import sqlite3
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pydantic_core
from sqlalchemy import Connection, Engine, Insert, Select, create_engine, event, text
from sqlalchemy.engine import Dialect, make_url
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


@dataclass(frozen=True)
class LoneStatement:
    """A Core ``SELECT`` or ``INSERT`` compiled once for a dialect, to run on a pooled DBAPI connection without
    SQLAlchemy's execution machinery (:meth:`Registry.fetch_one`, :meth:`Registry.insert_one`): its SQL text, how
    to make the driver's parameters (the columns' bind processors: a JSON column's value written by the engine's
    serialiser, a timestamp as SQLite's text), and for a ``SELECT`` the result processors of its columns (what a
    Core ``execute`` applies: a SQLite timestamp's text made a timezone-aware ``datetime``, for instance)."""

    compiled: Any
    """The statement compiled for the dialect (``SQLCompiler``)."""
    bind_processors: Mapping[str, Callable[[Any], Any]]
    """By parameter name, the conversion of its value for the driver (only the parameters that have one)."""
    result_processors: tuple[Callable[[Any], Any] | None, ...]
    """By column of a ``SELECT``, the conversion of the driver's value (None: taken as it is)."""

    @classmethod
    def of(cls, statement: Select[Any] | Insert, dialect: Dialect, keys: Sequence[str] = ()) -> LoneStatement:
        """``statement`` compiled for ``dialect`` (an ``INSERT`` of the columns ``keys``), with its columns' and
        parameters' conversions."""
        compiled = statement.compile(dialect=dialect, column_keys=list(keys) if keys else None)
        binds = {}
        for name, bind in compiled.binds.items():
            process = bind.type.dialect_impl(dialect).bind_processor(dialect)
            if process is not None:
                binds[name] = process
        columns = statement.selected_columns if isinstance(statement, Select) else ()
        results = tuple(c.type.dialect_impl(dialect).result_processor(dialect, None) for c in columns)
        return cls(compiled, binds, results)

    def parameters(self, values: Mapping[str, Any]) -> Any:
        """The driver's parameters for ``values`` of the statement's bound parameters (its constants, such as a
        ``LIMIT``, filled in): a sequence in the SQL's order for a positional paramstyle, else a mapping."""
        params = self.compiled.construct_params(values)
        for name, process in self.bind_processors.items():
            if name in params:
                params[name] = process(params[name])
        if self.compiled.positional:
            return tuple(params[name] for name in self.compiled.positiontup)
        return params

    def row(self, raw: Any) -> tuple[Any, ...]:
        """A driver's row with each column's result processor applied."""
        return tuple(v if p is None else p(v) for p, v in zip(self.result_processors, raw, strict=True))


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
        self._lone_statements: dict[tuple[int, tuple[str, ...]], tuple[Any, LoneStatement]] = {}
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

    def fetch_one(self, statement: Select[Any], values: Mapping[str, Any]) -> tuple[Any, ...] | None:
        """The first row of ``statement`` with its bound parameters set to ``values`` (None: no row), with the
        values a Core ``execute`` gives (the columns' result processors applied), run on a pooled DBAPI connection
        as :meth:`read_core` runs it (its own transaction on SQLite, one rolled back at the end elsewhere) but
        without SQLAlchemy's execution context: for the hot reads of one indexed row, where that context costs
        several times the query (about 50 us against 5-10 us on SQLite). The statement is compiled once per
        registry (keep ``statement`` a module-level constant: it is cached by identity). Errors are the driver's
        own (not wrapped in SQLAlchemy's exceptions)."""
        prepared = self._lone(statement)
        params = prepared.parameters(values)
        conn = self.engine.raw_connection()
        try:
            cursor = conn.cursor()
            try:
                cursor.execute(prepared.compiled.string, params)
                raw = cursor.fetchone()
            finally:
                cursor.close()
        finally:
            conn.close()  # back to the pool, which rolls back what the driver began
        return None if raw is None else prepared.row(raw)

    def insert_one(self, statement: Insert, values: Mapping[str, Any]) -> None:
        """``statement`` (an ``INSERT`` of one row) with ``values`` (by column key: the columns inserted) on a pooled
        DBAPI connection in this process's turn to write, committed when it returns, as :meth:`write_core` runs
        it (its own transaction on SQLite) but without SQLAlchemy's execution context (about 0.1 ms less for a
        stored plan's row). The values are converted by the columns' bind processors, as a Core ``execute``
        converts them (JSON by :func:`json_text`). The statement is compiled once per registry and set of
        columns (keep it a module-level constant). Errors are the driver's own."""
        prepared = self._lone(statement, tuple(values))
        params = prepared.parameters(values)
        with self._writer():
            conn = self.engine.raw_connection()
            try:
                cursor = conn.cursor()
                try:
                    cursor.execute(prepared.compiled.string, params)
                finally:
                    cursor.close()
                conn.commit()
            finally:
                conn.close()

    def _lone(self, statement: Select[Any] | Insert, keys: tuple[str, ...] = ()) -> LoneStatement:
        """``statement`` compiled for this registry's dialect (kept by identity and ``keys``)."""
        kept = self._lone_statements.get((id(statement), keys))
        if kept is None or kept[0] is not statement:
            kept = (statement, LoneStatement.of(statement, self.engine.dialect, keys))
            self._lone_statements[(id(statement), keys)] = kept
        return kept[1]

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
