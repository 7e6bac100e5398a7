"""``softsig signature closure --criterion``, run as a user runs it (a subprocess), on uploaded-style markers."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

SOFTSIG = [sys.executable, "-m", "softsig_service.cli"]
NAMES = ("thumb", "index", "middle", "ring", "little", "wrist", "p6")


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*SOFTSIG, *args], capture_output=True, text=True, timeout=300, env=dict(os.environ))


@pytest.fixture(scope="module")
def markers(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A flat hand [m, hand frame]: half-widths 60, 30, 4 mm along x, y, z growing to 80, 27, 9 mm (the long
    axis +20 mm = +33 %, the thin one +5 mm = +125 %), as a CSV time,point,x,y,z."""
    initial = np.array([0.060, 0.030, 0.004])
    final = np.array([0.080, 0.027, 0.009])
    unit = np.vstack([np.eye(3), -np.eye(3), [[0.1, -0.2, 0.3]]])
    lines = ["time,point,x,y,z"]
    for t, s in enumerate(np.linspace(0.0, 1.0, 5)):
        pts = unit * (initial + s * (final - initial)) + [0.0, 0.02, 0.09]
        lines += [f"{t * 0.1!r},{name},{x!r},{y!r},{z!r}" for name, (x, y, z) in zip(NAMES, pts.tolist(), strict=True)]
    path = tmp_path_factory.mktemp("markers") / "flat.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_the_criterion_option_elects_the_axis_and_shows_in_the_json(markers: Path) -> None:
    res = run("signature", "closure", "--markers", str(markers), "--json")
    assert res.returncode == 0, res.stderr
    absolute = json.loads(res.stdout)
    assert absolute["params"]["criterion"] == "absolute" and absolute["extras"]["magnitude_unit"] == "m"
    axis = absolute["axis"]  # written as the REST API writes vectors
    np.testing.assert_allclose([axis["x"], axis["y"], axis["z"]], [1.0, 0.0, 0.0], atol=1e-9)
    assert absolute["magnitude"] == pytest.approx(0.020, abs=1e-8)

    res = run("signature", "closure", "--markers", str(markers), "--criterion", "relative", "--json")
    assert res.returncode == 0, res.stderr
    relative = json.loads(res.stdout)
    assert relative["params"]["criterion"] == "relative" and relative["extras"]["magnitude_unit"] == "1"
    axis = relative["axis"]
    np.testing.assert_allclose([axis["x"], axis["y"], axis["z"]], [0.0, 0.0, 1.0], atol=1e-9)
    assert relative["magnitude"] == pytest.approx(1.25, abs=1e-6)
    assert relative["extras"]["absolute_change"][0] == pytest.approx(0.005, abs=1e-8)

    text = run("signature", "closure", "--markers", str(markers), "--criterion", "relative")
    assert text.returncode == 0, text.stderr
    assert "ellipsoid, relative criterion" in text.stdout and "[1]" in text.stdout


def test_pca_accepts_and_ignores_the_criterion_and_a_bad_one_is_named(markers: Path) -> None:
    res = run("signature", "closure", "--markers", str(markers), "--method", "pca", "--criterion", "relative", "--json")
    assert res.returncode == 0, res.stderr
    assert "criterion" not in json.loads(res.stdout)["params"]
    bad = run("signature", "closure", "--markers", str(markers), "--criterion", "percent")
    assert bad.returncode == 2
    assert "field: criterion" in bad.stderr and "absolute" in bad.stderr and "Traceback" not in bad.stderr
