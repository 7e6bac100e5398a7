"""Operations: health, readiness, Prometheus metrics by route template, request ids, JSON logs, error shapes,
and the committed OpenAPI document."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
from pathlib import Path

from api_helpers import AUTH, assert_problem
from fastapi.testclient import TestClient

from softsig_service.api.app import openapi_json
from softsig_service.api.logging import JsonFormatter, request_id_var

ROOT = Path(__file__).resolve().parents[2]


def test_health_and_readiness(api: TestClient) -> None:
    assert api.get("/healthz").json() == {"status": "ok"}
    ready = api.get("/readyz")
    assert ready.status_code == 200 and ready.json()["status"] == "ready"
    assert ready.json()["checks"]["registry"] == "ok"


def test_metrics_count_requests_by_route_template(api: TestClient) -> None:
    plan = api.post("/v1/plans", json={"hand": "sdm_hand", "object": {"kind": "builtin", "name": "apple"},
                                       "strategy": "S"}, headers=AUTH).json()  # fmt: skip
    for _ in range(3):
        assert api.get(f"/v1/plans/{plan['id']}").status_code == 200
    api.get("/v1/nothing/here")
    text = api.get("/metrics").text
    line = next(
        ln for ln in text.splitlines()
        if ln.startswith("softsig_http_requests_total{") and 'route="/v1/plans/{plan_id}"' in ln and 'status="200"' in ln
    )  # fmt: skip
    assert float(line.rsplit(" ", 1)[1]) >= 3.0
    assert plan["id"] not in text, "raw paths are never labels"
    assert 'route="unmatched"' in text
    assert "softsig_http_request_duration_seconds_bucket" in text and 'softsig_plan_seconds_count{strategy="S"}' in text


def test_request_id_in_and_out(api: TestClient) -> None:
    r = api.get("/healthz", headers={"X-Request-ID": "robot-42.step_7"})
    assert r.headers["x-request-id"] == "robot-42.step_7"
    r = api.get("/healthz", headers={"X-Request-ID": "bad id with spaces"})
    assert r.headers["x-request-id"] != "bad id with spaces" and len(r.headers["x-request-id"]) == 32
    p = api.get("/v1/hands/nobody", headers={"X-Request-ID": "trace-1"})
    assert assert_problem(p, 404, "hand")["request_id"] == "trace-1"


def test_json_log_lines_carry_the_request_id() -> None:
    token = request_id_var.set("req-123")
    try:
        record = logging.LogRecord("softsig.access", logging.INFO, __file__, 1, "GET %s %d", ("/x", 200), None)
        record.route = "/x"
        line = json.loads(JsonFormatter().format(record))
    finally:
        request_id_var.reset(token)
    assert line["request_id"] == "req-123" and line["message"] == "GET /x 200" and line["route"] == "/x"
    assert line["level"] == "info" and line["ts"].endswith("+00:00")


def test_unknown_routes_and_methods_are_problems(api: TestClient) -> None:
    assert_problem(api.get("/v1/nothing"), 404)
    r = api.patch("/v1/hands", headers=AUTH)
    assert_problem(r, 405)
    assert "GET" in r.headers["allow"]


def test_openapi_file_is_the_apps_schema() -> None:
    committed = (ROOT / "openapi" / "openapi.json").read_text(encoding="utf-8")
    assert committed == openapi_json(), "openapi/openapi.json is stale: run `softsig openapi`"
    doc = json.loads(committed)
    ops = [(m, p) for p, item in doc["paths"].items() for m in item]
    assert len(ops) >= 18
    assert doc["components"]["securitySchemes"]["APIKeyHeader"]["name"] == "X-API-Key"
    plan_post = doc["paths"]["/v1/plans"]["post"]
    assert "application/problem+json" in plan_post["responses"]["422"]["content"]


def test_openapi_command_check(tmp_path: Path) -> None:
    out = tmp_path / "openapi.json"
    cmd = [sys.executable, "-m", "softsig_service.cli", "openapi", "--out", str(out)]
    assert subprocess.run([*cmd, "--check"], capture_output=True, timeout=120).returncode == 1
    assert subprocess.run(cmd, capture_output=True, timeout=120).returncode == 0
    assert out.read_text(encoding="utf-8") == openapi_json()
    assert subprocess.run([*cmd, "--check"], capture_output=True, timeout=120).returncode == 0
