"""Safe loading of a hand's model files: path checks, size limits, and the asset map handed to MuJoCo.

A hand lives in one folder: its manifest, its MJCF or URDF and any mesh files. Every file a model refers to
must stay inside that folder: absolute paths, ``file://`` URLs and paths that climb out with ``..`` are
rejected (:class:`~softsig_service.errors.UnsafePath`), and so are files beyond the size limits of
:class:`~softsig_service.config.ModelLimits` (:class:`~softsig_service.errors.ModelTooLarge`).

URDF ``package://PKG/rel/path`` mesh references are resolved inside the hand folder (as ``rel/path`` or
``PKG/rel/path``) without editing the URDF file: the text is rewritten in memory only.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from softsig_service.config import ModelLimits
from softsig_service.errors import InvalidHandModel, ModelTooLarge, UnsafePath

MAX_PATH_CHARS = 1024
MAX_PATH_PARTS = 32
MAX_NAME_BYTES = 200
"""Limits of a file path in a hand's folder: characters, folders deep, bytes of one name (the file system's
limit is 255; the rest is left for softsig's own suffixes)."""


@dataclass(frozen=True)
class ModelSource:
    """A model ready for ``mujoco.MjSpec.from_string``: the XML text and the asset bytes it names."""

    xml: str
    assets: dict[str, bytes]
    model_dir: Path


def check_relative_path(ref: str, field: str) -> PurePosixPath:
    """``ref`` as a relative POSIX path, or :class:`UnsafePath` if it is absolute, a URL or climbs out with ``..``."""
    if ref.startswith(("file:", "http:", "https:", "/", "\\")) or (len(ref) > 1 and ref[1] == ":"):
        raise UnsafePath("asset paths must be relative to the hand's folder", field=field, value=ref)
    if len(ref) > MAX_PATH_CHARS or ref.count("/") + ref.count("\\") >= MAX_PATH_PARTS:
        raise UnsafePath(
            f"asset paths are at most {MAX_PATH_CHARS} characters in at most {MAX_PATH_PARTS} parts", field=field,
            value=ref,
        )  # fmt: skip
    rel = PurePosixPath(ref.replace("\\", "/"))
    if ".." in rel.parts:
        raise UnsafePath("asset paths must not leave the hand's folder", field=field, value=ref)
    for part in rel.parts:
        try:
            size = len(part.encode("utf-8"))
        except UnicodeEncodeError:
            raise UnsafePath("asset paths must be valid Unicode text", field=field, value=ref) from None
        if size > MAX_NAME_BYTES or "\0" in part:
            raise UnsafePath(f"a file or folder name is at most {MAX_NAME_BYTES} bytes", field=field, value=ref)
    return rel


def inside(folder: Path, rel: PurePosixPath, field: str, ref: str) -> Path:
    """``folder / rel`` with links resolved, or :class:`UnsafePath` (naming ``ref``) if that leaves ``folder``."""
    try:
        path = (folder / rel).resolve()
    except (OSError, RuntimeError):
        raise InvalidHandModel("referenced file cannot be read", field=field, value=ref) from None
    if not path.is_relative_to(folder.resolve()):
        raise UnsafePath("asset path resolves outside the hand's folder", field=field, value=ref)
    return path


def read_limited(path: Path, limit: int, field: str, shown: str) -> bytes:
    """The bytes of ``path`` (at most ``limit``); errors name ``field`` and ``shown`` (the model's own words)."""
    try:
        if not path.is_file():
            raise InvalidHandModel("referenced file not found in the hand's folder", field=field, value=shown)
        size = path.stat().st_size
        if size > limit:
            raise ModelTooLarge(f"file larger than the limit of {limit} bytes", field=field, value=size)
        return path.read_bytes()
    except OSError:
        raise InvalidHandModel("referenced file cannot be read", field=field, value=shown) from None


def read_model_text(path: Path, limits: ModelLimits, field: str = "model") -> str:
    """Read an MJCF/URDF file within the size limit; raise with ``field`` on a missing or oversized file."""
    data = read_limited(path, limits.max_model_bytes, field, path.name)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InvalidHandModel("model file is not UTF-8 text", field=field, value=path.name) from exc


def parse_xml(text: str, field: str) -> ET.Element:
    """The root element of ``text``, or :class:`InvalidHandModel` naming ``field``."""
    try:
        return ET.fromstring(text)
    except ET.ParseError as exc:
        raise InvalidHandModel(f"model is not well-formed XML: {exc}", field=field) from None


def _resolve_package(folder: Path, ref: str, field: str) -> Path:
    """``package://PKG/a/b.stl`` -> the first of ``a/b.stl`` and ``PKG/a/b.stl`` inside ``folder``."""
    body = ref[len("package://") :]
    parts = PurePosixPath(check_relative_path(body, field))
    candidates = [PurePosixPath(*parts.parts[1:]), parts] if len(parts.parts) > 1 else [parts]
    for cand in candidates:
        path = inside(folder, cand, field, ref)
        if path.is_file():
            return path
    raise InvalidHandModel(
        "package:// mesh not found in the hand's folder",
        field=field,
        value=ref,
        choices=[str(c) for c in candidates],
    )


def load_urdf_source(
    path: Path, limits: ModelLimits, hand_root: Path | None = None, text: str | None = None
) -> ModelSource:
    """Read a URDF and every collision mesh it names, ready for MuJoCo, without touching the file on disk.

    ``text``, when given, is the URDF itself (a xacro's expansion) and ``path`` only locates it: relative mesh
    paths resolve against ``path``'s folder.
    ``hand_root`` (default: the URDF's folder) is the hand's folder: ``package://`` references resolve inside
    it and no file may lie outside it; plain relative mesh paths resolve against the URDF's own folder.
    ``<visual>`` elements are dropped (MuJoCo simulates collision geometry; visual formats such as COLLADA
    cannot be loaded). Mesh references become flat asset names; a ``<mujoco><compiler/></mujoco>`` block is
    added in memory so that fixed links are kept as bodies (reference points may name them).
    """
    folder = (hand_root or path.parent).resolve()
    if not path.resolve().is_relative_to(folder):
        raise UnsafePath("the URDF must lie inside the hand's folder", field="model", value=path.name)
    if text is None:
        text = read_model_text(path, limits)
    elif len(text.encode()) > limits.max_model_bytes:
        raise ModelTooLarge(f"expanded URDF larger than {limits.max_model_bytes} bytes", field="model",
                            value=len(text.encode()))  # fmt: skip
    root = parse_xml(text, "model")
    if root.tag != "robot":
        raise InvalidHandModel("a URDF's root element must be <robot>", field="model", value=root.tag)
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    assets: dict[str, bytes] = {}
    total = len(text)
    for k, mesh in enumerate(root.iter("mesh")):
        ref = mesh.get("filename")
        field = f"model: mesh[{k}].filename"
        if not ref:
            raise InvalidHandModel("mesh without filename", field=field)
        if ref.startswith("package://"):
            file = _resolve_package(folder, ref, field)
        else:
            rel = check_relative_path(ref, field)
            file = (path.parent / rel).resolve()
            if not file.is_relative_to(folder):
                raise UnsafePath("asset path resolves outside the hand's folder", field=field, value=ref)
        data = read_limited(file, limits.max_asset_bytes, field, ref)
        name = f"asset{k:04d}_{file.name}"
        assets[name] = data
        total += len(data)
        mesh.set("filename", name)
        if len(assets) > limits.max_assets:
            raise ModelTooLarge(f"more than {limits.max_assets} asset files", field="model", value=len(assets))
        if total > limits.max_total_bytes:
            raise ModelTooLarge(f"model and assets exceed {limits.max_total_bytes} bytes", field="model", value=total)
    for old in root.findall("mujoco"):
        root.remove(old)
    ext = ET.SubElement(root, "mujoco")
    ET.SubElement(
        ext,
        "compiler",
        {
            "fusestatic": "false",
            "discardvisual": "true",
            "strippath": "false",
            "balanceinertia": "true",
            "boundmass": "1e-4",
            "boundinertia": "1e-9",
        },
    )
    return ModelSource(xml=ET.tostring(root, encoding="unicode"), assets=assets, model_dir=folder)
