"""An MJCF hand as text plus an in-memory asset dictionary: MuJoCo never opens a file of the host.

MuJoCo looks a file up in the asset dictionary (its virtual file system) first and falls back to the disk when
the name is not there, so handing it the dictionary is not enough. Here:

* ``<include>`` elements are expanded in memory (the included file's children take the element's place), so
  MuJoCo's parser opens no file at all;
* every attribute whose name starts with ``file`` (``file``, ``fileright`` … ``fileback``, ``filename``) is
  allowed only on ``<mesh>``, ``<skin>``, ``<hfield>`` and ``<texture>``; the file it names is read from the
  hand's folder (checked path, size limit) into the dictionary;
* after parsing, :func:`confine_spec` rewrites every file the spec names (meshes, skins, height fields, textures
  and their six cube faces) to its key in the dictionary and rejects any that is not there, so compiling can only
  read the dictionary. The same check runs on URDF hands.

Errors name the attribute and the value the model gave, never a resolved host path.
"""

from __future__ import annotations

import posixpath
import xml.etree.ElementTree as ET
from pathlib import Path, PurePosixPath
from typing import Any

from softsig_service.config import ModelLimits
from softsig_service.errors import InvalidHandModel, ModelTooLarge, UnsafePath
from softsig_service.hands.assets import ModelSource, check_relative_path, inside, parse_xml, read_limited

_MESH_TAGS = ("mesh", "skin", "hfield")
_FILE_TAGS = (*_MESH_TAGS, "texture")
_MAX_INCLUDE_DEPTH = 16


def _is_file_attr(attr: str) -> bool:
    return attr.startswith("file")


def _expand_includes(root: ET.Element, folder: Path, limits: ModelLimits, depth: int, budget: list[int]) -> None:
    """Replace each ``<include file>`` below ``root`` by the children of the included file's root, in place."""
    for parent in list(root.iter()):
        for pos, child in reversed(list(enumerate(parent))):
            if child.tag != "include":
                continue
            ref = child.get("file")
            field = "model: <include> file"
            if ref is None:
                raise InvalidHandModel("<include> without file", field=field)
            if depth >= _MAX_INCLUDE_DEPTH:
                raise InvalidHandModel(f"includes nested deeper than {_MAX_INCLUDE_DEPTH}", field=field, value=ref)
            rel = check_relative_path(ref, field)
            data = read_limited(inside(folder, rel, field, ref), limits.max_model_bytes, field, ref)
            budget[0] += len(data)
            try:
                sub = parse_xml(data.decode("utf-8"), field)
            except UnicodeDecodeError:
                raise InvalidHandModel("included file is not UTF-8 text", field=field, value=ref) from None
            if sub.tag != "mujoco":
                raise InvalidHandModel("an included file's root element must be <mujoco>", field=field, value=ref)
            _expand_includes(sub, folder, limits, depth + 1, budget)
            parent.remove(child)
            for k, grandchild in enumerate(list(sub)):
                parent.insert(pos + k, grandchild)


def _compiler_dirs(root: ET.Element) -> dict[str, str]:
    """``meshdir`` and ``texturedir`` as MuJoCo sets them (``assetdir`` sets both; the last compiler wins)."""
    dirs: dict[str, str] = {}
    for comp in root.iter("compiler"):
        for attr in ("assetdir", "meshdir", "texturedir"):
            value = comp.get(attr)
            if value:
                check_relative_path(value, f"compiler.{attr}")
                for key in ("meshdir", "texturedir") if attr == "assetdir" else (attr,):
                    dirs[key] = value
    return dirs


def asset_key(directory: str, ref: str) -> str:
    """The dictionary key of ``ref`` inside ``directory`` (both relative; ``.`` and doubled slashes folded)."""
    return posixpath.normpath(posixpath.join(directory.replace("\\", "/"), ref.replace("\\", "/")))


def load_mjcf_source(path: Path, limits: ModelLimits) -> ModelSource:
    """The MJCF at ``path`` with includes expanded and every file it names read into the asset dictionary."""
    folder = path.parent.resolve()
    data = read_limited(path, limits.max_model_bytes, "model", path.name)
    try:
        root = parse_xml(data.decode("utf-8"), "model")
    except UnicodeDecodeError:
        raise InvalidHandModel("model file is not UTF-8 text", field="model", value=path.name) from None
    budget = [len(data)]
    _expand_includes(root, folder, limits, 0, budget)
    dirs = _compiler_dirs(root)
    assets: dict[str, bytes] = {}
    for k, el in enumerate(root.iter()):
        for attr, ref in el.attrib.items():
            if not _is_file_attr(attr) or not ref:
                continue
            field = f"model: <{el.tag}> #{k} {attr}"
            if el.tag not in _FILE_TAGS:
                raise InvalidHandModel(f"<{el.tag}> may not name a file in a hand model", field=field, value=ref)
            check_relative_path(ref, field)
            key = asset_key(dirs.get("meshdir" if el.tag in _MESH_TAGS else "texturedir", ""), ref)
            rel = check_relative_path(key, field)
            if key not in assets:
                assets[key] = read_limited(inside(folder, rel, field, ref), limits.max_asset_bytes, field, ref)
                budget[0] += len(assets[key])
    if len(assets) > limits.max_assets:
        raise ModelTooLarge(f"more than {limits.max_assets} asset files", field="model", value=len(assets))
    if budget[0] > limits.max_total_bytes:
        raise ModelTooLarge(f"model and assets exceed {limits.max_total_bytes} bytes", field="model", value=budget[0])
    return ModelSource(xml=ET.tostring(root, encoding="unicode"), assets=assets, model_dir=folder)


def _confined(assets: dict[str, bytes], directory: str, ref: str, field: str) -> str:
    key = asset_key(directory, ref)
    if PurePosixPath(ref).is_absolute() or key not in assets:
        raise UnsafePath("the model names a file that is not one of the hand's files", field=field, value=ref)
    return key


def confine_spec(spec: Any, assets: dict[str, bytes]) -> None:
    """Point every file of ``spec`` at its key in ``assets``; :class:`UnsafePath` for any file not there."""
    meshdir, texturedir = spec.meshdir or "", spec.texturedir or ""
    for kind, items in (("mesh", spec.meshes), ("skin", spec.skins), ("hfield", spec.hfields)):
        for item in items:
            if item.file:
                item.file = _confined(assets, meshdir, item.file, f"model: <{kind} name='{item.name}'> file")
    for tex in spec.textures:
        field = f"model: <texture name='{tex.name}'>"
        if tex.file:
            tex.file = _confined(assets, texturedir, tex.file, f"{field} file")
        cube = list(tex.cubefiles)
        if any(cube):
            tex.cubefiles = [_confined(assets, texturedir, f, f"{field} cube file") if f else "" for f in cube]
    spec.meshdir = ""
    spec.texturedir = ""
    spec.strippath = False
