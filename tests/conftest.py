"""Shared fixtures: settings; the registry's databases (SQLite and PostgreSQL); MuJoCo is imported with a
headless (EGL) rendering backend."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from db_backends import Backend, PostgresCluster, find_server_bin

from softsig_service.config import Settings
from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()  # before any test module imports MuJoCo

DB_BACKENDS = ("sqlite", "postgresql")
"""The databases the registry and API tests run on, with the same assertions."""


def pytest_report_header() -> str:
    """Say at the top of the run which databases the registry and API tests use."""
    bin_dir = find_server_bin()
    if bin_dir is None:
        return (
            "registry backends: sqlite; postgresql NOT INSTALLED, its tests are skipped (scripts/test.sh installs it)"
        )
    return f"registry backends: sqlite, postgresql (a throwaway cluster of {bin_dir})"


@pytest.fixture(scope="session")
def settings() -> Settings:
    return Settings()


@pytest.fixture(scope="session")
def postgres_cluster() -> Iterator[PostgresCluster]:
    """A throwaway PostgreSQL server for this test process; its tests skip where no server is installed."""
    bin_dir = find_server_bin()
    if bin_dir is None:
        pytest.skip("PostgreSQL server not installed (no initdb; scripts/test.sh installs Debian's postgresql)")
    cluster = PostgresCluster(bin_dir)
    try:
        cluster.start()
        yield cluster
    finally:
        cluster.stop()


@pytest.fixture(scope="session", params=DB_BACKENDS)
def db_backend(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Backend:
    """The database kind of a registry or API test: every such test runs once on each."""
    if request.param == "postgresql":
        return Backend("postgresql", cluster=request.getfixturevalue("postgres_cluster"))
    return Backend("sqlite", folder=tmp_path_factory.mktemp("sqlite"))


@pytest.fixture()
def database_url(db_backend: Backend) -> Iterator[str]:
    """The URL of an empty database of this test's kind, dropped after the test."""
    url = db_backend.new_url()
    yield url
    db_backend.drop(url)
