"""Schema migrations on SQLite and PostgreSQL: a registry at the first revision with data in it is upgraded and
keeps its data; a registry made before migrations is adopted; a newer schema is refused; the migrations make the
models' schema; concurrent starts upgrade once."""

from __future__ import annotations

import threading
from typing import Any

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import Engine, text

from softsig_service import registry as repo
from softsig_service.registry.db import Registry, make_engine
from softsig_service.registry.migrate import FIRST_REVISION, SchemaTooNew, current_revision, head_revision, upgrade
from softsig_service.registry.models import Base

# rows written as the first revision's schema knows them (plain SQL: later models may differ)
_ROWS: list[tuple[str, dict[str, Any]]] = [
    ("INSERT INTO hands (id, name, builtin, revision, manifest_path, folder, files, info, signature_count, "
     "created_at, updated_at) VALUES (1, 'old_hand', false, 3, '/d/old_hand/hand.toml', '/d/old_hand', '[]', "
     "'{\"kind\": \"soft\"}', 2, :t, :t)", {}),
    ("INSERT INTO signatures (hand_id, version, kind, method, source, hand_revision, params, data, created_at) "
     "VALUES (1, 1, 'closure', 'pca', 'simulation', 3, '{}', '{\"axis\": [0, 0, 1]}', :t)", {}),
    ("INSERT INTO signatures (hand_id, version, kind, method, source, hand_revision, params, data, created_at) "
     "VALUES (1, 2, 'stiffness', 'apple', 'simulation', 3, '{}', '{\"k\": 250.0}', :t)", {}),
    ("INSERT INTO plans (id, hand, strategy, success, request, result, created_at) VALUES ('p0001', 'old_hand', "
     "'C', true, '{\"a\": 1}', '{\"b\": 2}', :t)", {}),
    ("INSERT INTO jobs (id, kind, status, progress, message, params, result, error, time_limit, cancel_requested, "
     "created_at) VALUES ('j0001', 'validation', 'succeeded', 1.0, 'done', '{}', '{\"ok\": true}', NULL, 60.0, "
     "false, :t)", {}),
]  # fmt: skip


def _at_first_revision_with_data(url: str) -> Engine:
    engine = make_engine(url)
    with engine.begin() as conn:
        assert upgrade(conn, FIRST_REVISION) == FIRST_REVISION
        for statement, params in _ROWS:
            conn.execute(text(statement), {"t": "2026-01-02 03:04:05+00:00", **params})
    return engine


def _assert_the_data_is_there(reg: Registry) -> None:
    hand = repo.get_hand(reg, "old_hand")
    assert (hand.revision, hand.folder, hand.info, hand.signature_count) == (3, "/d/old_hand", {"kind": "soft"}, 2)
    assert hand.created_at.year == 2026 and hand.created_at.utcoffset() is not None
    sigs, total = repo.list_signatures(reg, "old_hand")
    assert total == 2 and [(s.version, s.kind) for s in sigs] == [(2, "stiffness"), (1, "closure")]
    assert repo.get_signature(reg, "old_hand", 1).data == {"axis": [0, 0, 1]}
    assert repo.get_plan(reg, "p0001").result == {"b": 2}
    job = repo.get_job(reg, "j0001")
    assert job.status == "succeeded" and job.result == {"ok": True}
    # the version counter carries on after the upgrade
    new = repo.add_signature(reg, "old_hand", kind="closure", method="pca", source="simulation", data={})
    assert new.version == 3


def _revision(url: str) -> str | None:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return current_revision(conn)
    finally:
        engine.dispose()


def test_a_registry_at_the_first_revision_is_upgraded_and_keeps_its_data(database_url: str) -> None:
    _at_first_revision_with_data(database_url).dispose()
    assert _revision(database_url) == FIRST_REVISION
    reg = Registry(database_url)  # what the service does at start
    try:
        assert _revision(database_url) == head_revision()
        _assert_the_data_is_there(reg)
        assert reg.upgrade_schema() == head_revision(), "a second start changes nothing"
    finally:
        reg.dispose()


def test_a_registry_made_before_migrations_is_adopted(database_url: str) -> None:
    engine = _at_first_revision_with_data(database_url)
    with engine.begin() as conn:  # as create_all left it: the tables, no version table
        conn.execute(text("DROP TABLE alembic_version"))
    engine.dispose()
    assert _revision(database_url) is None
    reg = Registry(database_url)
    try:
        assert _revision(database_url) == head_revision()
        _assert_the_data_is_there(reg)
    finally:
        reg.dispose()


def test_a_newer_schema_is_refused_and_left_alone(database_url: str) -> None:
    Registry(database_url).dispose()
    engine = make_engine(database_url)
    with engine.begin() as conn:
        conn.execute(text("UPDATE alembic_version SET version_num = '9999_from_the_future'"))
    engine.dispose()
    with pytest.raises(SchemaTooNew, match="written by a newer softsig") as caught:
        Registry(database_url)
    assert "9999_from_the_future" in str(caught.value) and head_revision() in str(caught.value)
    assert _revision(database_url) == "9999_from_the_future"


def test_the_migrations_make_the_models_schema(database_url: str) -> None:
    reg = Registry(database_url)
    try:
        with reg.engine.connect() as conn:
            diff = compare_metadata(MigrationContext.configure(conn, opts={"compare_type": True}), Base.metadata)
        assert diff == [], "the models changed without a migration (alembic revision --autogenerate)"
    finally:
        reg.dispose()


def test_concurrent_starts_upgrade_once(database_url: str) -> None:
    errors: list[BaseException] = []
    registries: list[Registry] = []

    def start() -> None:
        try:
            registries.append(Registry(database_url, busy_timeout=30.0))
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=start) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert not any(t.is_alive() for t in threads), "a start is stuck"
    assert errors == []
    assert _revision(database_url) == head_revision()
    repo.add_hand(registries[0], name="h", manifest_path="/h/hand.toml", info={})
    assert [h.name for h in repo.list_hands(registries[-1])] == ["h"]
    for r in registries:
        r.dispose()
