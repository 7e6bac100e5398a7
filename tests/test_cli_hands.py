"""The ``softsig hands`` commands, run as a user runs them (a subprocess of the installed console script)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

SOFTSIG = [sys.executable, "-m", "softsig_service.cli"]


def run(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*SOFTSIG, *args], capture_output=True, text=True, timeout=300, env={**os.environ, **(env or {})}
    )


def test_hands_list_text_is_a_table_aligned_under_its_headings() -> None:
    res = run("hands", "list")
    assert res.returncode == 0, res.stderr
    head, *rows = res.stdout.splitlines()
    assert head.split() == ["name", "kind", "joints", "acts", "description"]
    pisa = next(r for r in rows if r.startswith("pisa_iit_softhand "))
    joints = next(
        r["joints"] for r in json.loads(run("hands", "list", "--json").stdout) if r["name"] == "pisa_iit_softhand"
    )
    # numbers end where their headings end (right-aligned), text starts where its heading starts
    assert pisa[: head.index("joints") + len("joints")].endswith(f" {joints}")
    assert pisa[head.index("kind") :].startswith("underactuated")
    assert pisa[head.index("description") :].startswith("Pisa/IIT SoftHand")


def test_hands_list_json() -> None:
    res = run("hands", "list", "--json")
    assert res.returncode == 0, res.stderr
    rows = json.loads(res.stdout)
    names = {r["name"] for r in rows}
    assert {"pisa_iit_softhand", "sdm_hand", "rbo_hand2", "parallel_gripper"} <= names
    pisa = next(r for r in rows if r["name"] == "pisa_iit_softhand")
    assert pisa["actuators"] == 1 and pisa["reference_points"] == 6


def test_hands_show_json_and_unknown_hand() -> None:
    res = run("hands", "show", "pisa_iit_softhand", "--json")
    assert res.returncode == 0, res.stderr
    info = json.loads(res.stdout)
    assert info["frame_id"] == "hand" and info["mount"] == "mount"
    assert [p["name"] for p in info["reference_points"]][-1] == "wrist"
    assert info["physical"]["synergy"]["thumb_abduction"] == 1.3
    bad = run("hands", "show", "nonexistent")
    assert bad.returncode == 2
    assert "field: hand" in bad.stderr and "pisa_iit_softhand" in bad.stderr and "Traceback" not in bad.stderr


def test_hands_close_writes_the_trajectory_json(tmp_path: Path) -> None:
    out = tmp_path / "traj.json"
    res = run("hands", "close", "sdm_hand", "--out", str(out))
    assert res.returncode == 0, res.stderr
    data = json.loads(out.read_text())
    assert set(data) == {"hand", "frame_id", "times", "point_names", "positions"}
    assert data["frame_id"] == "hand" and data["hand"] == "sdm_hand"
    T, N = len(data["times"]), len(data["point_names"])
    assert len(data["positions"]) == T and all(len(f) == N and all(len(p) == 3 for p in f) for f in data["positions"])


def test_hands_close_from_a_manifest_path(tmp_path: Path) -> None:
    manifest = Path(__file__).resolve().parent.parent / "hands" / "parallel_gripper" / "hand.toml"
    res = run("hands", "close", str(manifest), "--out", str(tmp_path / "t.json"))
    assert res.returncode == 0, res.stderr


def test_render_writes_a_png(tmp_path: Path) -> None:
    out = tmp_path / "hand.png"
    res = run("hands", "render", "parallel_gripper", "--out", str(out), "--size", "128")
    if res.returncode == 2 and "OpenGL backend" in res.stderr:
        pytest.skip("no OpenGL backend on this machine: " + res.stderr.strip())
    assert res.returncode == 0, res.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_render_refuses_an_unknown_cs_method(tmp_path: Path) -> None:
    res = run("hands", "render", "parallel_gripper", "--out", str(tmp_path / "x.png"), "--cs-method", "nonsense")
    assert res.returncode == 2 and "cs_method" in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "x.png").exists()


def test_render_without_a_usable_backend_fails_with_a_clear_message(tmp_path: Path) -> None:
    res = run("hands", "render", "parallel_gripper", "--out", str(tmp_path / "x.png"), env={"MUJOCO_GL": "nonsense"})
    assert res.returncode == 2
    assert "OpenGL backend" in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "x.png").exists()


MINI_HAND = Path(__file__).resolve().parent / "hands" / "data" / "mini_hand" / "hand.toml"


def test_hands_show_prints_the_hand_frame_axes() -> None:
    res = run("hands", "show", str(MINI_HAND))
    assert res.returncode == 0, res.stderr
    # mount_pose rpy (pi/2, 0, pi/2): hand +x along base_link +y, hand +z (the approach) along base_link +x
    assert "hand frame in 'base_link': origin (+0.000, +0.000, +0.000) m" in res.stdout
    assert "+x (+0.000, +1.000, +0.000)" in res.stdout and "+z (+1.000, +0.000, +0.000)" in res.stdout
    assert "expanded URDF sha256" in res.stdout and "mimic couplings: 6" in res.stdout


def test_render_draws_the_hand_frame_axes(tmp_path: Path) -> None:
    import matplotlib.image

    out = tmp_path / "mini.png"
    res = run("hands", "render", str(MINI_HAND), "--out", str(out), "--size", "160")
    if res.returncode == 2 and "OpenGL backend" in res.stderr:
        pytest.skip("no OpenGL backend on this machine: " + res.stderr.strip())
    assert res.returncode == 0, res.stderr
    rgb = matplotlib.image.imread(out)[..., :3]
    red = (rgb[..., 0] > 0.6) & (rgb[..., 1] < 0.25) & (rgb[..., 2] < 0.25)
    blue = (rgb[..., 2] > 0.6) & (rgb[..., 0] < 0.35) & (rgb[..., 1] < 0.5)
    assert red.sum() > 20 and blue.sum() > 20  # the x (red) and z (blue) arrows in both views
