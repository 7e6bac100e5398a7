"""xacro descriptions: expansion with arguments and $(find), the cache and its hash, and every refused escape."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from mini_hand import mini_hand

from softsig_service.config import ModelLimits, Settings
from softsig_service.errors import ExpansionLimit, InvalidHandModel, InvalidManifest, UnsafeDescription
from softsig_service.hands import xacro_expand
from softsig_service.hands.model import load_hand
from softsig_service.hands.xacro_expand import CACHE_DIR, expand_xacro


def _f1_origin(xml: str) -> str:
    k = xml.index('<joint name="f1_prox"')
    k = xml.index("<origin", k)
    return xml[k : xml.index("/>", k)]


def test_expansion_with_args_find_and_package_meshes(tmp_path: Path) -> None:
    toml = mini_hand(tmp_path)
    folder = toml.parent
    file = folder / "urdf" / "minihand.urdf.xacro"
    right = expand_xacro(file, folder, {"left": "false"}, ModelLimits())
    left = expand_xacro(file, folder, {"left": "true"}, ModelLimits())
    # the finger macro came through $(find minihand_description) = the hand's folder; the argument mirrors f1
    assert 'xyz="0.06 -0.02 0.025"' in _f1_origin(right.xml)
    assert 'xyz="0.06 0.02 0.025"' in _f1_origin(left.xml)
    assert right.sha256 != left.sha256 and right.files == ("urdf/finger.xacro", "urdf/minihand.urdf.xacro")
    assert str(tmp_path) not in right.xml  # xacro's banner with the absolute path is removed
    # loaded through the manifest: the expansion's hash is stored in the hand's summary
    hand = load_hand(str(toml), Settings())
    assert hand.expanded is not None and hand.expanded.sha256 == right.sha256
    assert hand.model.nmesh == 4 and hand.model.njnt == 7  # palm + three proximal phalanges (STL)


def test_expansion_is_cached_by_content(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    toml = mini_hand(tmp_path)
    folder = toml.parent
    file = folder / "urdf" / "minihand.urdf.xacro"
    first = expand_xacro(file, folder, {}, ModelLimits())
    assert (folder / CACHE_DIR / f"{first.key}.json").is_file()
    xacro_expand._MEMORY.clear()
    runs: list[Path] = []
    real = xacro_expand._run_sandbox
    monkeypatch.setattr(xacro_expand, "_run_sandbox", lambda f, *a: runs.append(f) or real(f, *a))
    again = expand_xacro(file, folder, {}, ModelLimits())  # from the disk cache: no new process
    assert again.sha256 == first.sha256 and runs == []
    finger = folder / "urdf" / "finger.xacro"
    finger.write_text(finger.read_text().replace('upper="1.2"', 'upper="1.1"'))
    changed = expand_xacro(file, folder, {}, ModelLimits())  # an included file changed: expanded again
    assert runs == [file] and changed.sha256 != first.sha256


# a real escape from xacro's expression sandbox (plain xacro runs it): reach os.system through object's subclasses
COMMAND = (Path(__file__).parent / "data" / "evil" / "command.xacro").read_text()
COMMAND = COMMAND[COMMAND.index("<xacro:property") : COMMAND.index("</robot>")]


@pytest.mark.parametrize(
    ("body", "error", "words"),
    [
        ('<xacro:include filename="/etc/hostname"/>', UnsafeDescription, "reads a file outside the hand's folder"),
        ('<xacro:include filename="$(find other_pkg)/../../secret.xacro"/>', UnsafeDescription, "outside"),
        ("<link name=\"${xacro.load_yaml('../outside.yaml')}\"/>", UnsafeDescription, "outside the hand's folder"),
        ('<link name="$(env HOME)"/>', UnsafeDescription, "reads an environment variable"),
        (COMMAND, UnsafeDescription, "runs a command"),
        ('<xacro:macro name="m"><xacro:m/></xacro:macro><xacro:m/>', ExpansionLimit, "recurses without end"),
        ("<link name=\"${'a' * 10**11}\"/>", ExpansionLimit, "memory limit"),
        ('<link name="${python.sum(python.range(10**12))}"/>', ExpansionLimit, "endless"),
        ('<link name="${undefined_name}"/>', InvalidHandModel, "could not be expanded"),
    ],
)
def test_unsafe_or_endless_descriptions_are_refused(
    tmp_path: Path, body: str, error: type[Exception], words: str
) -> None:
    folder = tmp_path / "hand"
    folder.mkdir()
    (tmp_path / "outside.yaml").write_text("a: 1\n")
    (tmp_path / "secret.xacro").write_text('<robot xmlns:xacro="http://www.ros.org/wiki/xacro"/>\n')
    file = folder / "evil.urdf.xacro"
    file.write_text(f'<robot name="evil" xmlns:xacro="http://www.ros.org/wiki/xacro">{body}</robot>\n')
    # the endless case must hit a short limit; the others get a long one, so that a busy machine's slow start of
    # the expansion process is not taken for an endless expansion
    seconds = 3.0 if words == "endless" else 60.0
    with pytest.raises(error) as info:
        expand_xacro(file, folder, {}, ModelLimits(xacro_seconds=seconds))
    if words == "endless":  # the wall-time or the CPU-time limit (both 3 s) stops it, whichever comes first
        words = "within 3 s" if "within 3 s" in str(info.value) else "stopped by its time or memory limit"
    assert type(info.value) is error and words in str(info.value)
    assert info.value.field == "model"  # type: ignore[attr-defined]
    assert not (folder / "MARKER").exists() and not (tmp_path / "MARKER").exists()


def test_manifest_rules_for_xacro(tmp_path: Path) -> None:
    toml = mini_hand(tmp_path, xacro_args="{ left = [1, 2] }")
    with pytest.raises(InvalidManifest) as info:
        load_hand(str(toml), Settings())
    assert info.value.field is not None and info.value.field.startswith("xacro_args")
    toml = mini_hand(tmp_path / "b", model='"urdf/minihand.urdf"')
    text = toml.read_text()
    with pytest.raises(InvalidManifest, match="xacro"):
        load_hand(str(toml), Settings())
    toml.write_text(textwrap.dedent(text).replace("xacro_args = { left = false }\n", ""))
    with pytest.raises(InvalidHandModel, match="not found"):
        load_hand(str(toml), Settings())
