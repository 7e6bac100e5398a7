"""A hand model cannot read a file of the host through any file-bearing attribute, and its errors never tell
whether a host file exists (MJCF and URDF; real MuJoCo parse and compile)."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import mujoco
import pytest

from softsig_service.config import Settings
from softsig_service.errors import SoftsigError, UnsafePath
from softsig_service.hands.mjcf_source import confine_spec
from softsig_service.hands.model import load_hand
from tests.hands.test_loading import MJCF_WITH_MESH, POSTURE, URDF, write_box_stl


def png(size: int = 4) -> bytes:
    """A real RGB PNG of ``size`` x ``size`` grey pixels."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    raw = b"".join(b"\0" + b"\x80" * (3 * size) for _ in range(size))
    head = struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", head) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


CUBE = ("fileright", "fileleft", "fileup", "filedown", "filefront", "fileback")

# each case: (snippet placed in <asset> or <worldbody>, where); {ref} is the host path under attack
CASES: dict[str, tuple[str, str]] = {
    **{
        f"texture-{face}": (
            '<texture name="t" type="cube" '
            + " ".join(f'{f}="{{ref}}"' if f == face else f'{f}="ok.png"' for f in CUBE)
            + "/>",
            "asset",
        )
        for face in CUBE
    },
    "texture-file": ('<texture name="t" type="2d" file="{ref}"/>', "asset"),
    "mesh-file": ('<mesh name="m2" file="{ref}"/>', "asset"),
    "hfield-file": ('<hfield name="h" file="{ref}" size="1 1 1 0.1"/>', "asset"),
    "skin-file": ('<skin name="s" file="{ref}"/>', "asset"),
    "model-file": ('<model name="mm" file="{ref}"/>', "asset"),
    "include-file": ('<include file="{ref}"/>', "root"),
    "flexcomp-file": ('<body><flexcomp name="fc" type="mesh" file="{ref}" dim="2"/></body>', "worldbody"),
}


def _hand_with(folder: Path, snippet: str, where: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    write_box_stl(folder / "meshes" / "palm.stl", (0.04, 0.02, 0.02))
    (folder / "ok.png").write_bytes(png())
    xml = MJCF_WITH_MESH.format(meshdir="meshes", file="palm.stl")
    if where == "asset":
        xml = xml.replace("</asset>", snippet + "</asset>")
    elif where == "worldbody":
        xml = xml.replace("</worldbody>", snippet + "</worldbody>")
    else:
        xml = xml.replace("<mujoco>", "<mujoco>" + snippet)
    (folder / "hand.xml").write_text(xml)
    (folder / "hand.toml").write_text(
        POSTURE.format(
            model="hand.xml",
            mount="mount",
            points="",
            open="j1 = 0.0, j2 = 0.0, j3 = 0.0",
            closed="j1 = -0.8, j2 = -0.8, j3 = -0.8",
        )
    )
    return folder / "hand.toml"


def _host_files(tmp_path: Path) -> dict[str, Path]:
    """A real host file of each kind outside the hand's folder, and one that does not exist."""
    host = tmp_path / "host"
    host.mkdir()
    (host / "secret.png").write_bytes(png())
    write_box_stl(host / "secret.stl", (0.01, 0.01, 0.01))
    (host / "secret.xml").write_text("<mujoco><worldbody><geom name='leak' size='0.1'/></worldbody></mujoco>")
    return {"png": host / "secret.png", "stl": host / "secret.stl", "xml": host / "secret.xml"}


def _kind(case: str) -> str:
    return "xml" if case == "include-file" else "png" if case.startswith(("texture", "hfield")) else "stl"


def _error(toml: Path, settings: Settings) -> SoftsigError:
    with pytest.raises(SoftsigError) as info:
        load_hand(str(toml), settings)
    return info.value


@pytest.mark.parametrize("case", sorted(CASES))
def test_no_attribute_reads_a_host_file(tmp_path: Path, settings: Settings, case: str) -> None:
    secret = _host_files(tmp_path)[_kind(case)]
    snippet, where = CASES[case]
    seen = []
    for k, ref in enumerate((str(secret), str(secret.with_name("missing" + secret.suffix)), f"../host/{secret.name}")):
        err = _error(_hand_with(tmp_path / f"hand{k}", snippet.format(ref=ref), where), settings)
        text = f"{err.message} {err.field} {err.choices}"
        assert str(tmp_path / f"hand{k}") not in text  # the hand's own host folder is never shown
        seen.append((type(err), err.message, err.field))
    # an existing and a missing host file give the same answer: no oracle for what the host holds
    assert seen[0] == seen[1]


def test_relative_file_that_falls_back_to_the_working_directory_is_refused(
    tmp_path: Path, settings: Settings, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A name not among the hand's files must not be looked up on disk relative to the process's directory."""
    cwd = tmp_path / "cwd"
    (cwd / "t").mkdir(parents=True)
    (cwd / "t" / "secret.png").write_bytes(png())
    monkeypatch.chdir(cwd)
    spec = mujoco.MjSpec.from_string(
        '<mujoco><asset><texture name="t" type="cube" fileright="t/secret.png" fileleft="a.png" fileup="a.png" '
        'filedown="a.png" filefront="a.png" fileback="a.png"/></asset></mujoco>',
        assets={"a.png": png()},
    )
    with pytest.raises(UnsafePath) as info:
        confine_spec(spec, {"a.png": png()})
    assert "fileright" not in str(tmp_path) and info.value.value == "t/secret.png"


def test_cube_texture_inside_the_folder_still_compiles(tmp_path: Path, settings: Settings) -> None:
    faces = " ".join(f'{f}="ok.png"' for f in CUBE)
    toml = _hand_with(tmp_path / "hand", f'<texture name="t" type="cube" {faces}/>', "asset")
    hand = load_hand(str(toml), settings)
    assert hand.model.ntex == 1


@pytest.mark.parametrize(
    "element",
    [
        '<mesh filename="{ref}"/>',
        '<mesh filename="package://two_jaw_description/../host/{name}"/>',
        '<mesh filename="file://{ref}"/>',
    ],
)
def test_urdf_elements_cannot_read_host_files(tmp_path: Path, settings: Settings, element: str) -> None:
    secret = _host_files(tmp_path)["stl"]
    answers = []
    for k, target in enumerate((secret, secret.with_name("missing.stl"))):
        folder = tmp_path / f"h{k}"
        folder.mkdir()
        mesh = element.format(ref=target, name=target.name)
        urdf = URDF.replace('<mesh filename="package://two_jaw_description/meshes/collision/base.stl"/>', mesh)
        urdf = urdf.replace("<robot name=\"two_jaw\">", '<robot name="two_jaw"><material name="skin">'
                            f'<texture filename="{target}"/></material>')  # fmt: skip
        (folder / "h.urdf").write_text(urdf)
        write_box_stl(folder / "meshes" / "collision" / "jaw.stl", (0.01, 0.005, 0.03))
        (folder / "hand.toml").write_text(
            POSTURE.format(
                model="h.urdf", mount="base_link", points="", open="left_slide = 0.0", closed="left_slide = -0.04"
            )
        )
        err = _error(folder / "hand.toml", settings)
        assert str(folder) not in f"{err.message} {err.value} {err.field}"
        answers.append((type(err), err.field))
    assert answers[0] == answers[1]


def test_a_missing_manifest_does_not_show_its_host_path(tmp_path: Path, settings: Settings) -> None:
    from softsig_service.hands.manifest import load_manifest

    missing = tmp_path / "gone" / "hand.toml"
    for load in (lambda: load_hand(str(missing), settings), lambda: load_manifest(missing)):
        with pytest.raises(SoftsigError) as info:
            load()
        assert str(tmp_path) not in f"{info.value.message} {info.value.value}"
