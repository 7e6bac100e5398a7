"""Schema migrations of the registry (Alembic): the service brings its registry up to date at start.

The revisions are in ``migrations/versions``; ``0001`` is the schema as ``create_all`` made it before migrations
existed. :func:`upgrade` (called by :meth:`~softsig_service.registry.db.Registry.upgrade_schema`, so at every
service start) decides by what it finds:

* an empty database is upgraded from nothing to the newest revision (head);
* a registry made before migrations (its tables, no ``alembic_version``) is stamped ``0001``, then upgraded;
* a registry at an older revision is upgraded; one at head is left alone;
* a registry at a revision this code does not know — written by a newer softsig — is refused with
  :class:`SchemaTooNew`, and nothing is changed.

Several workers or replicas starting at once are serialised: the whole upgrade is one transaction that first
takes the registry's upgrade lock (a transaction-scoped advisory lock on PostgreSQL; the write lock of
``BEGIN IMMEDIATE`` on SQLite), and DDL is transactional on both, so the next one in finds the schema at head.
"""

from __future__ import annotations

import logging
from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from alembic.util import CommandError
from sqlalchemy import inspect, text
from sqlalchemy.engine import Connection

from softsig_service.errors import SoftsigError

log = logging.getLogger("softsig.registry")

MIGRATIONS_DIR = Path(__file__).resolve().parent / "migrations"
"""Alembic's script folder (``env.py``, ``versions/``)."""
FIRST_REVISION = "0001"
"""The schema that ``create_all`` made before migrations existed."""
_UPGRADE_LOCK_KEY = 0x50F751C  # PostgreSQL advisory lock id of the registry's schema upgrades


class SchemaTooNew(SoftsigError):
    """The registry's schema was written by a newer softsig: this code refuses to run on it."""


def alembic_config() -> Config:
    """Alembic's configuration of the registry (no ini file): the script folder in the package."""
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    return config


def head_revision() -> str:
    """The newest revision this code knows."""
    head = ScriptDirectory.from_config(alembic_config()).get_current_head()
    if head is None:
        raise RuntimeError(f"no migration revisions in {MIGRATIONS_DIR}")
    return head


def current_revision(connection: Connection) -> str | None:
    """The revision the database is at (None: never migrated)."""
    return MigrationContext.configure(connection).get_current_revision()


def _known(revision: str) -> bool:
    try:
        return ScriptDirectory.from_config(alembic_config()).get_revision(revision) is not None
    except CommandError:
        return False


def upgrade(connection: Connection, target: str = "head") -> str:
    """Bring the registry on ``connection`` to ``target`` (see the module's rules); returns its revision then.

    ``connection`` must be in a transaction that the caller commits (on SQLite, one begun with
    ``BEGIN IMMEDIATE``): the lock taken here, the stamp and the migrations all belong to it.
    """
    if connection.dialect.name == "postgresql":
        connection.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": _UPGRADE_LOCK_KEY})
    config = alembic_config()
    config.attributes["connection"] = connection
    current = current_revision(connection)
    if current is not None and not _known(current):
        message = (
            f"the registry's schema is at revision {current!r}, which this softsig does not know: it was written by "
            f"a newer softsig (this one's newest revision is {head_revision()!r}). Run that version, or point "
            "SOFTSIG_DATABASE_URL at another database; the registry was left unchanged."
        )
        log.error("%s", message)
        raise SchemaTooNew(message, field="database_url", value=current)
    if current is None and inspect(connection).has_table("hands"):
        log.info("registry made before migrations: stamping it at revision %s", FIRST_REVISION)
        command.stamp(config, FIRST_REVISION)
    command.upgrade(config, target)
    now = current_revision(connection)
    if now != current:
        log.info("registry schema upgraded from %s to %s", current or "nothing", now)
    return now or ""
