"""The registry on a real SQLite file and a real PostgreSQL server (``database_url``, tests/conftest.py): versions
under concurrency, ETags, cascades, restarts; SQLite's connection settings."""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from db_backends import Backend
from sqlalchemy import event, text

from softsig_service import registry as repo
from softsig_service.errors import Conflict, HandNotFound, NotFound, PreconditionFailed, ServiceBusy
from softsig_service.registry.db import Registry


@pytest.fixture()
def reg(database_url: str) -> Iterator[Registry]:
    r = Registry(database_url, busy_timeout=30.0)
    yield r
    r.dispose()


def _hand(reg: Registry, name: str = "h1") -> repo.HandRecord:
    return repo.add_hand(reg, name=name, manifest_path=f"/x/{name}/hand.toml", info={"kind": "soft"}, folder="/x")


def test_sqlite_connections_are_configured(tmp_path: Path) -> None:
    reg = Registry(f"sqlite:///{tmp_path / 'sub' / 'registry.sqlite3'}", busy_timeout=30.0)
    with reg.engine.connect() as conn:
        assert conn.execute(text("PRAGMA journal_mode")).scalar() == "wal"
        assert conn.execute(text("PRAGMA foreign_keys")).scalar() == 1
        assert conn.execute(text("PRAGMA busy_timeout")).scalar() == 30000
    assert reg.ping()
    reg.dispose()


def test_the_backend_is_the_one_asked_for(reg: Registry, db_backend: Backend) -> None:
    assert reg.engine.dialect.name == db_backend.name
    assert reg.is_sqlite == (db_backend.name == "sqlite")
    assert reg.ping()


def test_concurrent_versions_are_gapless(reg: Registry, database_url: str) -> None:
    _hand(reg, "h1")
    _hand(reg, "h2")
    n_threads, per_thread = 8, 25
    errors: list[BaseException] = []
    # half the writers go through a second engine of their own, as a second service worker would
    other = Registry(database_url, busy_timeout=30.0)

    def writer(k: int) -> None:
        try:
            for i in range(per_thread):
                repo.add_signature(other if k % 2 else reg, "h1" if (k + i) % 2 else "h2", kind="closure",
                                   method="pca", source="simulation", data={"k": k, "i": i})  # fmt: skip
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=writer, args=(k,)) for k in range(n_threads)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    other.dispose()
    assert not any(t.is_alive() for t in threads), "writers are stuck"
    assert errors == []
    total = 0
    for name in ("h1", "h2"):
        items, count = repo.list_signatures(reg, name, limit=1000)
        versions = sorted(s.version for s in items)
        assert versions == list(range(1, count + 1)), "1..N without gaps or duplicates"
        assert repo.get_hand(reg, name).signature_count == count
        total += count
    assert total == n_threads * per_thread
    payloads = {(s.data["k"], s.data["i"]) for n in ("h1", "h2") for s in repo.list_signatures(reg, n, limit=1000)[0]}
    assert len(payloads) == n_threads * per_thread, "every write is there"


def test_versions_if_match_and_revisions(reg: Registry) -> None:
    h = _hand(reg)
    assert re.fullmatch(r'"h1\.r1\.[0-9a-f]{8}"', h.etag)
    s1 = repo.add_signature(reg, "h1", kind="closure", method="ellipsoid", source="markers", data={"a": 1})
    with pytest.raises(PreconditionFailed):
        repo.add_signature(reg, "h1", kind="closure", method="pca", source="simulation", data={}, if_match='"h1.v7"')
    s2 = repo.add_signature(reg, "h1", kind="stiffness", method="apple", source="simulation", data={"b": 2},
                            if_match=s1.etag)  # fmt: skip
    assert (s1.version, s2.version) == (1, 2)
    assert repo.latest_signature(reg, "h1", kind="closure").version == 1
    assert repo.latest_signature(reg, "h1").version == 2
    with pytest.raises(NotFound):
        repo.get_signature(reg, "h1", 3)
    # a signature computed from an older revision of the hand is refused
    new, old_folder = repo.replace_hand(reg, "h1", if_match=h.etag, manifest_path="/y/hand.toml", folder="/y",
                                       files=[], info={})  # fmt: skip
    assert new.revision == 2 and old_folder == "/x"
    with pytest.raises(Conflict):
        repo.add_signature(reg, "h1", kind="closure", method="pca", source="simulation", data={}, hand_revision=1)
    with pytest.raises(PreconditionFailed):
        repo.delete_hand(reg, "h1", if_match=h.etag)
    assert repo.etag_matches(new.etag, '"zzz", ' + new.etag) and repo.etag_matches(new.etag, "*")
    assert not repo.etag_matches(None, "*")


def test_the_ellipsoid_criterion_reads_back(reg: Registry) -> None:
    _hand(reg)
    add = repo.add_signature
    relative = add(reg, "h1", kind="closure", method="ellipsoid", source="simulation", params={"criterion": "relative"},
                   data={"params": {"criterion": "relative"}, "extras": {"magnitude_unit": "1"}})  # fmt: skip
    absolute = add(reg, "h1", kind="closure", method="ellipsoid", source="markers", params={"method": "ellipsoid"},
                   data={"params": {"criterion": "absolute"}, "extras": {"magnitude_unit": "m"}})  # fmt: skip
    # stored without a criterion anywhere: its dimensionless magnitude says relative
    legacy = add(reg, "h1", kind="closure", method="ellipsoid", source="simulation",
                 data={"params": {"tol": 1e-7}, "extras": {"magnitude_unit": "1"}})  # fmt: skip
    pca = add(reg, "h1", kind="closure", method="pca", source="simulation", params={"criterion": "relative"},
              data={"extras": {"magnitude_unit": "m"}})  # fmt: skip
    unknown = add(reg, "h1", kind="closure", method="ellipsoid", source="simulation", data={"a": 1})
    assert [r.criterion for r in (relative, absolute, legacy, pca, unknown)] == [
        "relative", "absolute", "relative", None, None,
    ]  # fmt: skip
    back = {r.version: r.criterion for r in repo.list_signatures(reg, "h1")[0]}
    assert back == {relative.version: "relative", absolute.version: "absolute", legacy.version: "relative",
                    pca.version: None, unknown.version: None}  # fmt: skip
    assert repo.get_signature(reg, "h1", relative.version).params == {"criterion": "relative"}


def test_delete_cascades_and_builtins_are_read_only(reg: Registry) -> None:
    _hand(reg)
    repo.add_signature(reg, "h1", kind="closure", method="pca", source="simulation", data={})
    repo.delete_hand(reg, "h1", if_match=None)
    with reg.read() as s:
        assert s.execute(text("SELECT count(*) FROM signatures")).scalar() == 0
    with pytest.raises(HandNotFound):
        repo.get_hand(reg, "h1")
    assert repo.sync_builtin_hand(reg, name="b", manifest_path="/b/hand.toml", info={"v": 1}) == "added"
    assert repo.sync_builtin_hand(reg, name="b", manifest_path="/b/hand.toml", info={"v": 1}) == "unchanged"
    assert repo.sync_builtin_hand(reg, name="b", manifest_path="/b/hand.toml", info={"v": 2}) == "updated"
    assert repo.get_hand(reg, "b").revision == 2
    with pytest.raises(Conflict):
        repo.delete_hand(reg, "b", if_match=None)
    with pytest.raises(Conflict):
        _hand(reg, "b")


def test_workers_starting_together_register_each_builtin_hand_once(reg: Registry, database_url: str) -> None:
    workers = [Registry(database_url, busy_timeout=30.0) for _ in range(4)]
    barrier = threading.Barrier(len(workers))
    outcomes: list[str] = []
    errors: list[BaseException] = []

    def start(worker: Registry) -> None:
        barrier.wait()
        try:
            outcomes.append(repo.sync_builtin_hand(worker, name="b", manifest_path="/b/hand.toml", info={"v": 1}))
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=start, args=(w,)) for w in workers]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    for w in workers:
        w.dispose()
    assert errors == []
    assert sorted(outcomes) == ["added", "unchanged", "unchanged", "unchanged"]
    assert [(h.name, h.revision) for h in repo.list_hands(reg)] == [("b", 1)]


def test_jobs(reg: Registry) -> None:
    j = repo.add_job(reg, kind="validation", params={"trials": 3}, time_limit=10.0, max_unfinished=2)
    repo.add_job(reg, kind="validation", params={}, time_limit=10.0, max_unfinished=2)
    with pytest.raises(ServiceBusy):
        repo.add_job(reg, kind="validation", params={}, time_limit=10.0, max_unfinished=2)
    repo.update_job(reg, j.id, status="running", progress=0.5)
    done = repo.update_job(reg, j.id, status="succeeded", progress=1.0, result={"ok": True})
    assert done is not None and done.finished
    assert repo.update_job(reg, j.id, progress=0.7) is None, "a finished job stays finished"
    with pytest.raises(Conflict):
        repo.request_cancel(reg, j.id)


KINDS = ("validation",)


def test_a_job_is_claimed_by_one_process_and_only_its_holder_writes(reg: Registry) -> None:
    j = repo.add_job(reg, kind="validation", params={"n": 1}, time_limit=10.0, max_unfinished=9, private={"p": 2})
    assert repo.claim_job(reg, "a", 30.0, kinds=("experiment",), max_attempts=3) is None, "only the kinds asked"
    claim = repo.claim_job(reg, "a", 30.0, kinds=KINDS, max_attempts=3)
    assert claim is not None and claim.record.id == j.id and claim.private == {"p": 2}
    assert claim.record.status == "running" and claim.record.owner == "a" and claim.record.attempts == 1
    assert "p" not in repo.get_job(reg, j.id).params, "private parameters stay apart"
    assert repo.claim_job(reg, "b", 30.0, kinds=KINDS, max_attempts=3) is None, "a held job is not claimed twice"
    assert repo.update_job(reg, j.id, owner="b", progress=0.9) is None, "only the holder reports progress"
    assert repo.renew_lease(reg, j.id, "b", 30.0) is None
    renewed = repo.renew_lease(reg, j.id, "a", 30.0)
    assert renewed is not None and renewed.lease_expires_at is not None
    assert repo.update_job(reg, j.id, owner="b", status="succeeded") is None
    done = repo.update_job(reg, j.id, owner="a", status="succeeded", result={"ok": 1})
    assert done is not None and done.finished and done.lease_expires_at is None
    assert repo.renew_lease(reg, j.id, "a", 30.0) is None, "a finished job has no lease"


def test_an_expired_lease_is_claimed_again_until_the_attempts_run_out(reg: Registry) -> None:
    j = repo.add_job(reg, kind="validation", params={}, time_limit=10.0, max_unfinished=9)
    first = repo.claim_job(reg, "a", 0.05, kinds=KINDS, max_attempts=2)
    assert first is not None
    time.sleep(0.1)  # "a" died: its heartbeat stopped
    second = repo.claim_job(reg, "b", 0.05, kinds=KINDS, max_attempts=2)
    assert second is not None and second.record.id == j.id and second.record.attempts == 2
    assert second.record.owner == "b" and second.record.message.startswith("resumed")
    assert repo.update_job(reg, j.id, owner="a", status="succeeded") is None, "the dead holder's write is refused"
    time.sleep(0.1)
    assert repo.claim_job(reg, "c", 30.0, kinds=KINDS, max_attempts=2) is None
    failed = repo.get_job(reg, j.id)
    assert failed.status == "failed" and failed.error is not None and failed.error["type"] == "interrupted"


def test_release_and_cancel(reg: Registry) -> None:
    held = repo.add_job(reg, kind="validation", params={}, time_limit=10.0, max_unfinished=9)
    queued = repo.add_job(reg, kind="validation", params={}, time_limit=10.0, max_unfinished=9)
    assert repo.claim_job(reg, "a", 30.0, kinds=KINDS, max_attempts=3) is not None
    cancelled = repo.request_cancel(reg, queued.id)
    assert cancelled.status == "cancelled" and cancelled.finished, "a queued job nobody holds ends at once"
    running = repo.request_cancel(reg, held.id)
    assert running.status == "running" and running.cancel_requested, "the holder stops a running one"
    assert repo.release_jobs(reg, "a") == 1
    again = repo.get_job(reg, held.id)
    assert again.status == "queued" and again.owner is None
    # a released job whose cancellation was requested is cancelled by the next claim instead of run
    assert repo.claim_job(reg, "b", 30.0, kinds=KINDS, max_attempts=3) is None
    assert repo.get_job(reg, held.id).status == "cancelled"


def test_concurrent_claims_give_each_job_to_one_process(reg: Registry, database_url: str) -> None:
    ids = {repo.add_job(reg, kind="validation", params={}, time_limit=9.0, max_unfinished=99).id for _ in range(12)}
    got: dict[str, list[str]] = {}
    errors: list[BaseException] = []

    def worker(name: str) -> None:
        own = Registry(database_url)
        try:
            while (claim := repo.claim_job(own, name, 30.0, kinds=KINDS, max_attempts=3)) is not None:
                got.setdefault(name, []).append(claim.record.id)
        except BaseException as exc:
            errors.append(exc)
        finally:
            own.dispose()

    threads = [threading.Thread(target=worker, args=(f"w{k}",)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    claimed = [i for v in got.values() for i in v]
    assert errors == [] and sorted(claimed) == sorted(ids), "every job claimed exactly once"


def test_restart_keeps_the_registry(database_url: str) -> None:
    url = database_url
    first = Registry(url)
    _hand(first)
    plan = repo.add_plan(first, hand="h1", strategy="C", success=True, request={"a": 1}, result={"b": 2})
    first.dispose()
    second = Registry(url)
    assert repo.get_hand(second, "h1").name == "h1"
    assert repo.get_plan(second, plan.id).result == {"b": 2}
    second.dispose()


def test_lists_filter_page_and_count_newest_first(reg: Registry) -> None:
    """Jobs by kind and status, plans by hand: each page newest first, the total counts every match, a filter of
    None filters nothing, and records do not share their JSON with the stored rows."""
    ids = []
    for i in range(7):
        kind = "validation" if i % 2 == 0 else "experiment"
        ids.append(repo.add_job(reg, kind=kind, params={"i": i}, time_limit=60.0, max_unfinished=100).id)
        time.sleep(0.002)  # distinct creation times
    repo.update_job(reg, ids[0], status="succeeded")
    repo.update_job(reg, ids[2], status="succeeded")

    page, total = repo.list_jobs(reg, kind="validation", limit=2, offset=0)
    assert total == 4 and [j.id for j in page] == [ids[6], ids[4]]
    page, total = repo.list_jobs(reg, kind="validation", limit=2, offset=2)
    assert total == 4 and [j.id for j in page] == [ids[2], ids[0]]
    page, total = repo.list_jobs(reg, kind="validation", status="succeeded")
    assert total == 2 and [j.id for j in page] == [ids[2], ids[0]]
    page, total = repo.list_jobs(reg, kind=None, status=None, limit=3)
    assert total == 7 and [j.id for j in page] == ids[:3:-1]

    plans = []
    for hand in ("a", "b", "a"):
        plans.append(repo.add_plan(reg, hand=hand, strategy="C", success=True, request={"h": hand}, result={"r": 1}))
        time.sleep(0.002)
    page, total = repo.list_plans(reg, hand="a")
    assert total == 2 and [p.id for p in page] == [plans[2].id, plans[0].id]
    page[0].result["r"] = 2  # a record's JSON is its own
    assert repo.get_plan(reg, plans[2].id).result == {"r": 1}
    with pytest.raises(NotFound):
        repo.get_plan(reg, "0" * 32)


def test_a_plans_hand_reference_and_stored_plan_read_back(reg: Registry) -> None:
    """The plan route's Core paths: ``hand_ref`` gives what ``get_hand`` gives (and the revision after a
    replacement), an unknown name is ``HandNotFound`` with the registered names; a plan stored with ``add_plan``
    reads back equal, created_at timezone-aware, its record not sharing JSON with the caller."""
    _hand(reg, "h2")
    _hand(reg, "h1")
    ref = repo.hand_ref(reg, "h1")
    full = repo.get_hand(reg, "h1")
    assert (ref.name, ref.revision, ref.manifest_path) == (full.name, full.revision, full.manifest_path)
    repo.replace_hand(reg, "h1", if_match=full.etag, manifest_path="/y/h1/hand.toml", folder="/y", info={}, files=[])
    assert (repo.hand_ref(reg, "h1").revision, repo.hand_ref(reg, "h1").manifest_path) == (2, "/y/h1/hand.toml")
    with pytest.raises(HandNotFound) as err:
        repo.hand_ref(reg, "nope", field="body.hand")
    assert err.value.field == "body.hand" and err.value.choices == ["h1", "h2"]

    request, result = {"a": [1, 2]}, {"b": {"c": 0.5}}
    plan = repo.add_plan(reg, hand="h1", strategy="S", success=False, request=request, result=result)
    request["a"] = []
    stored = repo.get_plan(reg, plan.id)
    assert stored == plan and stored.request == {"a": [1, 2]} and stored.result == {"b": {"c": 0.5}}
    assert stored.created_at.utcoffset() is not None and not stored.success


def test_the_hot_reads_give_what_core_and_the_records_give(reg: Registry) -> None:
    """``Registry.fetch_one`` (the stamps, ``hand_ref``, ``newest_of_object``) gives the row a Core ``execute``
    gives, timestamps timezone-aware; a hand's stamp equals ``stamp_of`` its record (the answer caches' keys meet)
    and changes with a new revision and a new signature; a plan's stamp is its ``created_at``; no row is None."""
    from softsig_service.registry.hands import _STAMP_QUERY
    from softsig_service.registry.signatures import _NEWEST_OF_OBJECT

    _hand(reg, "h1")
    stamp = repo.hand_stamp(reg, "h1")
    assert stamp == repo.stamp_of(repo.get_hand(reg, "h1")) and stamp is not None
    assert stamp[2].utcoffset() is not None
    with reg.read_core() as conn:
        assert stamp == tuple(conn.execute(_STAMP_QUERY, {"name": "h1"}).one())
    assert repo.hand_stamp(reg, "nope") is None and repo.plan_stamp(reg, "0" * 32) is None
    full = repo.get_hand(reg, "h1")
    repo.replace_hand(reg, "h1", if_match=full.etag, manifest_path="/y/h1/hand.toml", folder="/y", info={}, files=[])
    replaced = repo.hand_stamp(reg, "h1")
    assert replaced != stamp and replaced == repo.stamp_of(repo.get_hand(reg, "h1"))
    assert repo.newest_of_object(reg, "h1", "capture", "d1") is None
    sig = repo.add_signature(reg, "h1", kind="capture", method="m", source="computed", data={}, object_digest="d1")
    assert repo.newest_of_object(reg, "h1", "capture", "d1") == (sig.version, sig.etag)
    with reg.read_core() as conn:
        row = conn.execute(_NEWEST_OF_OBJECT, {"hand": "h1", "kind": "capture", "digest": "d1"}).one()
    assert reg.fetch_one(_NEWEST_OF_OBJECT, {"hand": "h1", "kind": "capture", "digest": "d1"}) == tuple(row)
    assert repo.hand_stamp(reg, "h1") == repo.stamp_of(repo.get_hand(reg, "h1")) != replaced
    plan = repo.add_plan(reg, hand="h1", strategy="S", success=True, request={}, result={})
    assert repo.plan_stamp(reg, plan.id) == plan.created_at == repo.get_plan(reg, plan.id).created_at


def test_the_plan_paths_lone_statements_are_committed_at_once(reg: Registry, database_url: str) -> None:
    """``hand_ref`` and ``add_plan`` send their statement alone on SQLite (no BEGIN: SQLite makes a lone statement
    atomic), and the plan is committed when ``add_plan`` returns, on SQLite and on PostgreSQL: another registry on
    the same database reads it back at once. What SQLite runs is traced by SQLite itself (``hand_ref`` reads on a
    DBAPI connection, below SQLAlchemy's events)."""
    _hand(reg, "h1")
    sent: list[str] = []
    tracing = True

    def trace(statement: str) -> None:
        if tracing:
            sent.append(statement.split()[0].upper())

    def on_connect(dbapi_connection: Any, _record: object) -> None:
        if reg.is_sqlite:
            dbapi_connection.set_trace_callback(trace)

    reg.engine.dispose()  # connections made from here on are traced from their first statement
    event.listen(reg.engine, "connect", on_connect)
    try:
        ref = repo.hand_ref(reg, "h1")
        plan = repo.add_plan(reg, hand="h1", strategy="C", success=True, request={}, result={"q": [0.1]})
    finally:
        tracing = False
        event.remove(reg.engine, "connect", on_connect)
    if reg.is_sqlite:
        assert sent == ["SELECT", "INSERT"]
    assert ref.name == "h1"
    other = Registry(database_url, create=False)
    try:
        assert repo.get_plan(other, plan.id) == plan
    finally:
        other.dispose()


def test_sqlite_writers_of_one_process_queue_and_time_out_as_busy(tmp_path: Path) -> None:
    """On SQLite the threads of one process take turns before they reach SQLite's write lock: a writer that cannot
    have its turn within ``busy_timeout`` gets ``ServiceBusy`` (503 over HTTP), and the held write is not lost."""
    reg = Registry(f"sqlite:///{tmp_path / 'registry.sqlite3'}", busy_timeout=0.2)
    entered, release = threading.Event(), threading.Event()

    def hold() -> None:
        with reg.write():
            entered.set()
            release.wait(10)
            repo.add_plan(reg, hand="h", strategy="S", success=True, request={}, result={})  # re-entrant

    holder = threading.Thread(target=hold)
    holder.start()
    assert entered.wait(10)
    started = time.monotonic()
    with pytest.raises(ServiceBusy):
        repo.add_plan(reg, hand="h", strategy="C", success=True, request={}, result={})
    assert 0.15 <= time.monotonic() - started < 5.0
    release.set()
    holder.join(10)
    assert [p.strategy for p in repo.list_plans(reg)[0]] == ["S"]
    repo.add_plan(reg, hand="h", strategy="C", success=True, request={}, result={})
    assert repo.list_plans(reg)[1] == 2
    reg.dispose()
