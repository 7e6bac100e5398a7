"""The databases the registry and API tests run on: SQLite files, and a real PostgreSQL server.

The PostgreSQL server is a throwaway cluster made by ``initdb`` in a temporary folder and served by ``pg_ctl`` on
a Unix socket in that folder only (no TCP port, so parallel test workers never collide), with durability off
(``fsync``, ``synchronous_commit``: the data dies with the test run anyway). PostgreSQL refuses to run as root:
as root the cluster belongs to the ``postgres`` system user of Debian's package (``runuser``), else to whoever
runs the tests. Each test (or API module) gets a database of its own, dropped afterwards. A cluster left running
by a test process that was killed before its teardown is stopped and removed by the next one that starts.

The server's programs are looked up in ``SOFTSIG_PG_BIN``, then Debian's ``/usr/lib/postgresql/<version>/bin``
(newest first), then ``PATH``; ``scripts/test.sh`` installs Debian's ``postgresql`` where it is missing.
"""

from __future__ import annotations

import os
import pwd
import re
import shutil
import signal
import subprocess
import tempfile
import uuid
from pathlib import Path

import psycopg
from psycopg import sql

PG_USER = "softsig"
"""The cluster's superuser, used by the tests (trust authentication on the socket)."""
_PREFIX = "softsig-pg-"
"""Folders of the clusters: ``<tmp>/softsig-pg-<pid of the test process>-<random>``."""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def reap_stale_clusters() -> list[Path]:
    """Stop (immediate shutdown) and remove the clusters whose test process is gone; returns their folders."""
    reaped = []
    for root in Path(tempfile.gettempdir()).glob(f"{_PREFIX}*-*"):
        owner = re.fullmatch(rf"{_PREFIX}(\d+)-\w+", root.name)
        if owner is None or _alive(int(owner.group(1))):
            continue
        pid_file = root / "data" / "postmaster.pid"
        if pid_file.is_file():
            server = int(pid_file.read_text().split()[0])
            cmdline = Path(f"/proc/{server}/cmdline")
            if cmdline.is_file() and str(root).encode() in cmdline.read_bytes():
                os.kill(server, signal.SIGQUIT)  # the postmaster's immediate shutdown
        shutil.rmtree(root, ignore_errors=True)
        reaped.append(root)
    return reaped


def find_server_bin() -> Path | None:
    """The folder of ``initdb`` and ``pg_ctl`` (see the module's order), or None where no server is installed."""
    candidates: list[Path] = []
    if os.environ.get("SOFTSIG_PG_BIN"):
        candidates.append(Path(os.environ["SOFTSIG_PG_BIN"]))
    debian = Path("/usr/lib/postgresql")
    if debian.is_dir():
        versions = [p for p in debian.iterdir() if re.fullmatch(r"\d+", p.name)]
        candidates += [p / "bin" for p in sorted(versions, key=lambda p: int(p.name), reverse=True)]
    on_path = shutil.which("initdb")
    if on_path:
        candidates.append(Path(on_path).resolve().parent)
    return next((c for c in candidates if (c / "initdb").is_file() and (c / "pg_ctl").is_file()), None)


class PostgresCluster:
    """A PostgreSQL cluster in a temporary folder, serving only a Unix socket there."""

    def __init__(self, bin_dir: Path) -> None:
        self.bin_dir = bin_dir
        reap_stale_clusters()
        self.root = Path(tempfile.mkdtemp(prefix=f"{_PREFIX}{os.getpid()}-"))
        self.data = self.root / "data"
        self.log = self.root / "server.log"
        self._prefix: list[str] = []
        if os.geteuid() == 0:
            owner = pwd.getpwnam("postgres")  # made by Debian's postgresql-common
            os.chown(self.root, owner.pw_uid, owner.pw_gid)
            self._prefix = ["runuser", "-u", "postgres", "--"]

    def _run(self, *args: str) -> None:
        done = subprocess.run([*self._prefix, *args], capture_output=True, text=True, timeout=120, check=False)
        if done.returncode != 0:
            server_log = self.log.read_text(errors="replace")[-2000:] if self.log.exists() else ""
            raise RuntimeError(f"{args[0]} failed ({done.returncode}): {done.stderr[-2000:]}\n{server_log}")

    def start(self) -> None:
        """initdb, then start the server and wait until it accepts connections."""
        self._run(str(self.bin_dir / "initdb"), "-D", str(self.data), "-U", PG_USER, "--auth=trust",
                  "--encoding=UTF8", "--no-sync")  # fmt: skip
        options = f"-k {self.root} -c listen_addresses='' -c fsync=off -c synchronous_commit=off " \
                  "-c full_page_writes=off -c max_connections=200"  # fmt: skip
        self._run(str(self.bin_dir / "pg_ctl"), "-D", str(self.data), "-l", str(self.log), "-o", options, "-w",
                  "-t", "60", "start")  # fmt: skip

    def stop(self) -> None:
        """Stop the server (fast shutdown) and remove its folder."""
        try:
            self._run(str(self.bin_dir / "pg_ctl"), "-D", str(self.data), "-m", "fast", "-w", "stop")
        finally:
            shutil.rmtree(self.root, ignore_errors=True)

    def url(self, database: str, *, driver: str = "postgresql+psycopg") -> str:
        """The SQLAlchemy URL of ``database`` over the cluster's socket."""
        return f"{driver}://{PG_USER}@/{database}?host={self.root}"

    def _admin(self) -> psycopg.Connection[tuple[object, ...]]:
        return psycopg.connect(host=str(self.root), user=PG_USER, dbname="postgres", autocommit=True)

    def create_database(self) -> str:
        """A new empty database; returns its SQLAlchemy URL."""
        name = f"t_{uuid.uuid4().hex[:16]}"
        with self._admin() as conn:
            conn.execute(sql.SQL("CREATE DATABASE {}").format(sql.Identifier(name)))
        return self.url(name)

    def drop_database(self, url: str) -> None:
        """Drop the database of ``url`` (connections still open to it are closed)."""
        name = url.rsplit("/", 1)[1].split("?", 1)[0]
        with self._admin() as conn:
            conn.execute(sql.SQL("DROP DATABASE IF EXISTS {} WITH (FORCE)").format(sql.Identifier(name)))

    def server_version(self) -> str:
        """The server's version string (``SHOW server_version``)."""
        with self._admin() as conn:
            row = conn.execute("SHOW server_version").fetchone()
        return str(row[0]) if row else "?"


class Backend:
    """One kind of database for the tests: ``new_url()`` makes an empty database, ``drop(url)`` removes it."""

    def __init__(self, name: str, *, folder: Path | None = None, cluster: PostgresCluster | None = None) -> None:
        self.name = name
        self._folder = folder
        self._cluster = cluster

    def new_url(self) -> str:
        """The URL of a new, empty database of this kind."""
        if self._cluster is not None:
            return self._cluster.create_database()
        assert self._folder is not None
        return f"sqlite:///{self._folder / uuid.uuid4().hex / 'registry.sqlite3'}"

    def drop(self, url: str) -> None:
        """Remove the database of ``url`` (PostgreSQL; a SQLite file goes with the test's temporary folder)."""
        if self._cluster is not None:
            self._cluster.drop_database(url)
