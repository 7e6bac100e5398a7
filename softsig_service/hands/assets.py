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

_FILE_ATTRS = ("file", "filename")
_DIR_ATTRS = ("meshdir", "texturedir", "assetdir")


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
    rel = PurePosixPath(ref.replace("\\", "/"))
    if ".." in rel.parts:
        raise UnsafePath("asset paths must not leave the hand's folder", field=field, value=ref)
    return rel


def _inside(folder: Path, rel: PurePosixPath, field: str, ref: str) -> Path:
    path = (folder / rel).resolve()
    if not path.is_relative_to(folder.resolve()):
        raise UnsafePath("asset path resolves outside the hand's folder", field=field, value=ref)
    return path


def _read_limited(path: Path, limit: int, field: str) -> bytes:
    if not path.is_file():
        raise InvalidHandModel("referenced file not found in the hand's folder", field=field, value=path.name)
    size = path.stat().st_size
    if size > limit:
        raise ModelTooLarge(f"file larger than the limit of {limit} bytes", field=field, value=size)
    return path.read_bytes()


def read_model_text(path: Path, limits: ModelLimits, field: str = "model") -> str:
    """Read an MJCF/URDF file within the size limit; raise with ``field`` on a missing or oversized file."""
    data = _read_limited(path, limits.max_model_bytes, field)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InvalidHandModel("model file is not UTF-8 text", field=field, value=path.name) from exc


def _parse(text: str, field: str) -> ET.Element:
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
        path = _inside(folder, cand, field, ref)
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
        raise UnsafePath("the URDF must lie inside the hand's folder", field="model", value=str(path))
    if text is None:
        text = read_model_text(path, limits)
    elif len(text.encode()) > limits.max_model_bytes:
        raise ModelTooLarge(f"expanded URDF larger than {limits.max_model_bytes} bytes", field="model",
                            value=len(text.encode()))  # fmt: skip
    root = _parse(text, "model")
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
        data = _read_limited(file, limits.max_asset_bytes, field)
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


def check_mjcf_paths(path: Path, limits: ModelLimits, *, _seen: set[Path] | None = None) -> int:
    """Check every file an MJCF (and its includes) refers to stays in its folder; return total bytes.

    ``meshdir``/``texturedir``/``assetdir`` must be relative and inside the folder, and so must every
    ``file`` attribute resolved against them.
    """
    seen = _seen if _seen is not None else set()
    folder = path.parent
    text = read_model_text(path, limits, field="model" if not seen else f"include {path.name}")
    seen.add(path.resolve())
    root = _parse(text, "model")
    dirs: dict[str, PurePosixPath] = {}
    for comp in root.iter("compiler"):
        for attr in _DIR_ATTRS:
            if comp.get(attr):
                dirs[attr] = check_relative_path(comp.get(attr, ""), f"compiler.{attr}")
    total = len(text)
    count = 0
    for k, el in enumerate(root.iter()):
        for attr in _FILE_ATTRS:
            ref = el.get(attr)
            if ref is None:
                continue
            field = f"model: <{el.tag}> #{k} {attr}"
            rel = check_relative_path(ref, field)
            if el.tag == "include":
                inc = _inside(folder, rel, field, ref)
                if inc in seen:
                    raise InvalidHandModel("include cycle", field=field, value=ref)
                total += check_mjcf_paths(inc, limits, _seen=seen)
                continue
            base = dirs.get("meshdir" if el.tag in ("mesh", "skin") else "texturedir", dirs.get("assetdir"))
            file = _inside(folder, (base / rel) if base else rel, field, ref)
            total += len(_read_limited(file, limits.max_asset_bytes, field))
            count += 1
    if count > limits.max_assets:
        raise ModelTooLarge(f"more than {limits.max_assets} asset files", field="model", value=count)
    if total > limits.max_total_bytes:
        raise ModelTooLarge(f"model and assets exceed {limits.max_total_bytes} bytes", field="model", value=total)
    return total
