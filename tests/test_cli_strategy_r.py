"""Strategy R on the command line: build a capture model, plan and validate with it (subprocesses, as a user)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SOFTSIG = [sys.executable, "-m", "softsig_service.cli"]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*SOFTSIG, *args], capture_output=True, text=True, timeout=300)


def test_capture_model_then_r_plans_and_validations(tmp_path: Path) -> None:
    model = tmp_path / "capture.json"
    grid = ("--n-theta", "2", "--half-width", "0.01", "--step", "0.01", "--holdout", "0")
    res = run("signature", "capture", "parallel_gripper", "--object", "box", *grid, "--out", str(model), "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["simulations"] == 18 and model.is_file()
    common = ("--hand", "parallel_gripper", "--object", "box", "--strategy", "R", "--sigma-r", "0.1", "--sigma-t",
              "0.01")  # fmt: skip
    res = run("plan", *common, "--capture", str(model), "--json")
    assert res.returncode == 0, res.stderr
    plan = json.loads(res.stdout)
    assert plan["strategy"] == "R" and plan["success"] and 0.0 <= plan["quality"]["expected_capture"] <= 1.0
    res = run("validate", *common, "--capture", str(model), "--trials", "2", "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["trials"] == 2
    # without --capture: the model shipped with a built-in hand for a built-in object, else a clear error
    res = run("plan", *common, "--json")
    assert res.returncode == 0 and json.loads(res.stdout)["quality"]["expected_capture"] is not None, res.stderr
    custom = tmp_path / "box.json"
    custom.write_text(json.dumps({"kind": "box", "size": [0.12, 0.05, 0.05], "mass": 0.1}))
    res = run("plan", *common[:2], "--object", str(custom), *common[4:])
    assert res.returncode == 2 and "field: capture" in res.stderr, res.stderr
