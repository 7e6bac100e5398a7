"""A hand registered as one archive: the xacro test hand through the API (and ``softsig hands add``), every
rejection of an archive's members and sizes, and a refused xacro as a 422 naming the problem."""

from __future__ import annotations

import io
import subprocess
import sys
import tarfile
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from api_helpers import AUTH, KEY, assert_problem, make_settings
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app
from softsig_service.config import ModelLimits, Settings
from softsig_service.hands.archive import pack_folder
from softsig_service.hands.model import load_hand

MINI = Path(__file__).resolve().parents[1] / "hands" / "data" / "mini_hand"
BOX = {"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.05, "yaw": 0.4}}


def _files(name: str = "mini_hand") -> dict[str, bytes]:
    files = {p.relative_to(MINI).as_posix(): p.read_bytes() for p in MINI.rglob("*") if p.is_file()}
    files = {k: v for k, v in files.items() if not k.startswith(".softsig-cache")}
    files["hand.toml"] = files["hand.toml"].replace(b'name = "mini_hand"', f'name = "{name}"'.encode())
    return files


def _zip(files: dict[str, bytes], top: str = "") -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for rel, data in files.items():
            z.writestr(top + rel, data)
    return out.getvalue()


def _tar(members: list[tuple[tarfile.TarInfo, bytes | None]]) -> bytes:
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w:gz") as t:
        for info, data in members:
            t.addfile(info, io.BytesIO(data) if data is not None else None)
    return out.getvalue()


def _file(name: str, data: bytes) -> tuple[tarfile.TarInfo, bytes]:
    info = tarfile.TarInfo(name)
    info.size = len(data)
    return info, data


def _post(api: TestClient, name: str, data: bytes) -> object:
    return api.post("/v1/hands/archive", files=[("archive", (name, data))], headers=AUTH)


@pytest.fixture(scope="module")
def small_api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """An app whose limits are small enough to test the archive limits cheaply."""
    limits = ModelLimits(max_archive_members=20, max_asset_bytes=200_000, max_total_bytes=400_000)
    app = create_app(make_settings(tmp_path_factory.mktemp("small"), limits=limits))
    with TestClient(app) as client:
        yield client


def test_xacro_hand_with_mimics_round_trips_through_the_registry(api: TestClient) -> None:
    r = _post(api, "mini_hand.zip", _zip(_files(), top="minihand_description/"))
    assert r.status_code == 201, r.text  # type: ignore[attr-defined]
    body = r.json()  # type: ignore[attr-defined]
    assert body["model_format"] == "xacro" and r.headers["location"] == "/v1/hands/mini_hand"  # type: ignore[attr-defined]
    info = api.get("/v1/hands/mini_hand").json()["info"]
    local = load_hand(str(MINI / "hand.toml"), Settings())
    assert local.expanded is not None and info["expanded_urdf"]["sha256"] == local.expanded.sha256
    mimics = {m["joint"]: (m["root"], m["multiplier"], m["offset"]) for m in info["mimics"]}
    assert mimics["f1_dist"] == ("synergy_joint", pytest.approx(0.3), 0.0)  # chain f1_dist -> f1_prox -> root
    assert mimics["thumb_dist"] == ("synergy_joint", pytest.approx(0.15), pytest.approx(0.05))
    z = info["hand_frame"]["z"]  # a frame's axes are vectors, {x, y, z}, as everywhere on the wire
    assert [z["x"], z["y"], z["z"]] == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)
    assert {s["joint"] for s in info["synergy"]} == {"synergy_joint", *mimics}
    # like a built-in hand: a closure signature, then a plan with strategy C
    cs = api.post("/v1/hands/mini_hand/signatures/closure", json={}, headers=AUTH)
    assert cs.status_code == 201, cs.text
    plan = api.post("/v1/plans", json={"hand": "mini_hand", "object": BOX, "strategy": "C", "store": False},
                    headers=AUTH)  # fmt: skip
    assert plan.status_code in (200, 201), plan.text
    assert plan.json()["success"] is True, plan.json()["reasons"]
    # the same archive again: the name is taken
    assert_problem(_post(api, "mini_hand.tar.gz", pack_folder(MINI, ModelLimits())), 409, "manifest.name")


COMMAND_XACRO = (MINI.parent / "evil" / "command.xacro").read_bytes()  # runs a command under plain xacro


@pytest.mark.parametrize(
    ("xacro", "slug", "words"),
    [
        (COMMAND_XACRO, "unsafe-description", "runs a command"),
        (b'<robot xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:include filename="/etc/passwd"/></robot>',
         "unsafe-description", "outside the hand's folder"),
        (b'<robot xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:macro name="m"><xacro:m/></xacro:macro>'
         b"<xacro:m/></robot>", "expansion-limit", "recurses without end"),
    ],
)  # fmt: skip
def test_a_refused_xacro_is_a_422_naming_the_problem(api: TestClient, xacro: bytes, slug: str, words: str) -> None:
    files = _files("evil_hand")
    files["urdf/minihand.urdf.xacro"] = xacro
    body = assert_problem(_post(api, "evil.zip", _zip(files)), 422, "model")
    assert body["type"].endswith(slug) and words in body["detail"]
    assert api.get("/v1/hands/evil_hand").status_code == 404


def _link(name: str, target: str, kind: bytes) -> tuple[tarfile.TarInfo, None]:
    info = tarfile.TarInfo(name)
    info.type = kind
    info.linkname = target
    return info, None


BASE = [_file(rel, data) for rel, data in _files("bad_hand").items()]


@pytest.mark.parametrize(
    ("name", "members", "status", "words"),
    [
        ("h.tar.gz", [*BASE, _file("../escape.stl", b"x")], 422, "must not leave"),
        ("h.tar.gz", [*BASE, _file("/etc/cron.d/x", b"x")], 422, "relative"),
        ("h.tar.gz", [*BASE, _link("meshes/link.stl", "/etc/passwd", tarfile.SYMTYPE)], 422, "links"),
        ("h.tar.gz", [*BASE, _link("meshes/hard.stl", "hand.toml", tarfile.LNKTYPE)], 422, "links"),
        ("h.tar.gz", [*BASE, _link("dev/zero", "", tarfile.CHRTYPE)], 422, "only files and folders"),
        ("h.tar.gz", [*BASE, _file(".softsig-cache/x.json", b"{}")], 422, "cache"),
        ("h.tar.gz", [*BASE, *[_file(f"extra/{k}.txt", b"x") for k in range(20)]], 413, "members"),
        ("h.tar.gz", [*BASE, _file("big.bin", b"\0" * 200_001)], 413, "larger than 200000 bytes"),
        ("h.tar.gz", [*BASE, *[_file(f"z{k}.bin", b"\0" * 150_000) for k in range(3)]], 413, "unpacks to more"),
        ("h.tar.gz", [m for m in BASE if m[0].name != "hand.toml"], 422, "no hand.toml"),
        ("h.rar", BASE, 422, ".zip, .tar.gz"),
    ],
)
def test_archive_rejections(small_api: TestClient, name: str, members: list, status: int, words: str) -> None:  # type: ignore[type-arg]
    body = assert_problem(_post(small_api, name, _tar(members)), status, "archive")
    assert words in body["detail"], body
    assert small_api.get("/v1/hands/bad_hand").status_code == 404


def test_zip_with_a_symlink_member_is_refused(small_api: TestClient) -> None:
    import stat

    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for rel, data in _files("link_hand").items():
            z.writestr(rel, data)
        info = zipfile.ZipInfo("meshes/secret.stl")
        info.external_attr = (stat.S_IFLNK | 0o777) << 16
        z.writestr(info, "/etc/shadow")
    body = assert_problem(_post(small_api, "link.zip", out.getvalue()), 422, "archive")
    assert "links" in body["detail"] and body["value"] == "meshes/secret.stl"


def test_zip_bomb_stops_at_the_limit(small_api: TestClient) -> None:
    files = _files("bomb_hand")
    files["meshes/bomb.bin"] = b"\0" * 50_000_000  # deflates to about 50 kB
    data = _zip(files)
    assert len(data) < 200_000
    body = assert_problem(_post(small_api, "bomb.zip", data), 413, "archive")
    assert "meshes/bomb.bin" in str(body["value"])


def test_cli_hands_add_registers_a_folder(tmp_path: Path) -> None:
    from test_api_serve import serve

    with serve(tmp_path, tmp_path / "registry.sqlite3") as client:
        cmd = [sys.executable, "-m", "softsig_service.cli", "hands", "add", str(MINI), "--url",
               str(client._http.base_url).rstrip("/"), "--api-key", KEY]  # fmt: skip
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        assert "registered mini_hand" in res.stdout
        assert client.hand("mini_hand").model_format == "xacro"
        again = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert again.returncode == 2 and "409" in again.stderr and "manifest.name" in again.stderr
