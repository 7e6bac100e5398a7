"""Fixtures of the API tests: a real app (lifespan, worker processes) on a real database in a temporary folder,
once on SQLite and once on PostgreSQL (``db_backend``, tests/conftest.py)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from api_helpers import TEST_JOB_KINDS, make_settings
from db_backends import Backend
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory, db_backend: Backend) -> Iterator[TestClient]:
    """A client of one app per test module and database kind (the lifespan runs once)."""
    data = tmp_path_factory.mktemp("api")
    url = db_backend.new_url()
    app = create_app(make_settings(data, database_url=url), job_kinds=TEST_JOB_KINDS)
    with TestClient(app, raise_server_exceptions=True) as client:
        yield client
    db_backend.drop(url)
