"""Alembic's environment of the registry.

The service runs migrations through :func:`softsig_service.registry.migrate.upgrade`, which hands its own
connection (inside a transaction holding the registry's upgrade lock) in ``config.attributes["connection"]``.
Alembic's command line (``alembic -c softsig_service/registry/migrations/alembic.ini ...``) gets an engine for
the service's database from the settings (``SOFTSIG_DATABASE_URL``, else the SQLite file in the data dir).
``--sql`` (offline) mode writes the DDL for that URL's dialect instead.
"""

from __future__ import annotations

from alembic import context
from sqlalchemy.engine import Connection

from softsig_service.registry.models import Base


def _configure(connection: Connection) -> None:
    context.configure(
        connection=connection,
        target_metadata=Base.metadata,
        render_as_batch=connection.dialect.name == "sqlite",  # SQLite alters tables by copying them
        compare_type=True,
    )


def _database_url() -> str:
    url = context.config.get_main_option("sqlalchemy.url")
    if url:
        return url
    from softsig_service.config import Settings

    return Settings().resolved_database_url()


def run() -> None:
    """Run the migrations Alembic was asked for, online on a connection or offline as SQL."""
    if context.is_offline_mode():
        context.configure(url=_database_url(), target_metadata=Base.metadata, literal_binds=True)
        with context.begin_transaction():
            context.run_migrations()
        return
    given: Connection | None = context.config.attributes.get("connection")
    if given is not None:
        _configure(given)
        with context.begin_transaction():
            context.run_migrations()
        return
    from softsig_service.registry.db import make_engine

    engine = make_engine(_database_url())
    try:
        with engine.begin() as connection:
            _configure(connection)
            with context.begin_transaction():
                context.run_migrations()
    finally:
        engine.dispose()


run()
