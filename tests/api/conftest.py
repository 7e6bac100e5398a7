"""Fixtures of the API tests: a real app (lifespan, worker processes) on a real SQLite file in a temporary folder."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from api_helpers import TEST_JOB_KINDS, make_settings
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """A client of one app per test module (the lifespan runs once)."""
    data = tmp_path_factory.mktemp("api")
    app = create_app(make_settings(data), job_kinds=TEST_JOB_KINDS)
    with TestClient(app, raise_server_exceptions=True) as client:
        yield client
