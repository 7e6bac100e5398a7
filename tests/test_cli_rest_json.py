"""``softsig plan --json`` and ``POST /v1/plans`` write one JSON: the same keys, the same vector form
({"x", "y", "z"}), the same values, and no negative zero anywhere."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient

from softsig_service.api.app import create_app
from softsig_service.config import Settings

SERVICE_ONLY = {"id", "created_at", "links", "hand_revision"}
"""Keys only a stored plan of the service has (its identity and the registry's revision of the hand)."""


def _negative_zeros(value: Any, path: str = "$") -> list[str]:
    if isinstance(value, float):
        return [path] if value == 0.0 and str(value).startswith("-") else []
    if isinstance(value, dict):
        return [p for k, v in value.items() for p in _negative_zeros(v, f"{path}.{k}")]
    if isinstance(value, list):
        return [p for i, v in enumerate(value) for p in _negative_zeros(v, f"{path}[{i}]")]
    return []


def _differences(a: Any, b: Any, path: str = "$", tol: float = 1e-9) -> list[str]:
    """Where ``a`` and ``b`` differ in structure, type or value (numbers within ``tol``)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{path}: keys {sorted(set(a) ^ set(b))}"]
        return [d for k in a for d in _differences(a[k], b[k], f"{path}.{k}", tol)]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: lengths {len(a)} and {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True)) for d in _differences(x, y, f"{path}[{i}]", tol)]
    if isinstance(a, bool | str | None) or isinstance(b, bool | str | None):
        return [] if a == b and type(a) is type(b) else [f"{path}: {a!r} != {b!r}"]
    return [] if abs(float(a) - float(b)) <= tol else [f"{path}: {a!r} != {b!r}"]


def _without_timing(plan: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in plan.items() if k != "timing"}


def test_the_cli_and_the_service_write_the_same_plan(tmp_path: Path) -> None:
    args = ["plan", "--hand", "parallel_gripper", "--object", "box", "--x", "0.5", "--y", "0.05", "--yaw", "0.4",
            "--strategy", "S"]  # fmt: skip
    res = subprocess.run([sys.executable, "-m", "softsig_service.cli", *args, "--json"], capture_output=True,
                         text=True, timeout=300)  # fmt: skip
    assert res.returncode == 0, res.stderr
    cli = json.loads(res.stdout)
    settings = Settings(data_dir=tmp_path, api_keys=["k"], compute_workers=1, warm_planner=False)
    body = {"hand": "parallel_gripper", "object": {"kind": "builtin", "name": "box",
            "pose": {"x": 0.5, "y": 0.05, "yaw": 0.4}}, "strategy": "S"}  # fmt: skip
    with TestClient(create_app(settings)) as api:
        r = api.post("/v1/plans", json=body, headers={"X-API-Key": "k"})
    assert r.status_code == 201, r.text
    served = r.json()
    assert set(served) - SERVICE_ONLY == set(cli), set(served) ^ set(cli)
    assert set(served["timing"]) == set(cli["timing"])
    rest = _without_timing({k: v for k, v in served.items() if k not in SERVICE_ONLY})
    assert _differences(rest, _without_timing(cli)) == []
    assert isinstance(cli["approach"]["direction"], dict) and isinstance(cli["grasp_pose"]["position"], dict)
    assert _negative_zeros(cli) == [] and _negative_zeros(served) == []


def test_the_cli_draws_the_plan_with_the_service_s_function(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from softsig_service.cli import app
    from softsig_service.hands.model import resolve_hand_path
    from softsig_service.services.plan_image import render_plan_png

    image = tmp_path / "plan.png"
    out = CliRunner().invoke(app, ["plan", "--hand", "parallel_gripper", "--object", "box", "--strategy", "S",
                                   "--json", "--image", str(image)])  # fmt: skip
    assert out.exit_code == 0, out.output
    plan = json.loads(out.output)
    assert image.read_bytes() == render_plan_png(plan, str(resolve_hand_path("parallel_gripper")))
