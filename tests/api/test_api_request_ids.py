"""A 500 can be traced: its problem body carries the request's id, and so does the log line of its traceback."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest
from api_helpers import make_settings
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app


def test_an_unexpected_error_names_its_request_in_the_answer_and_the_log(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    app = create_app(make_settings(tmp_path))

    def broken() -> None:
        raise RuntimeError("a bug")

    app.add_api_route("/v1/broken", broken, methods=["GET"])
    with TestClient(app, raise_server_exceptions=False) as api, caplog.at_level(logging.ERROR):
        r = api.get("/v1/broken", headers={"X-Request-ID": "abc123def456"})
        mine = api.get("/v1/broken")
    assert r.status_code == 500 and r.headers["content-type"] == "application/problem+json", r.text
    body = r.json()
    assert body["type"].endswith("internal-error") and body["request_id"] == "abc123def456", body
    assert mine.json()["request_id"] == mine.headers["x-request-id"]
    tracebacks = [rec for rec in caplog.records if rec.exc_info and "a bug" in str(rec.exc_info[1])]
    assert [getattr(rec, "request_id", None) for rec in tracebacks] == ["abc123def456", mine.headers["x-request-id"]]
