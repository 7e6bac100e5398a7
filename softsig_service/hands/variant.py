"""A named variant of a hand: a copy of its folder whose manifest applies calibration values.

The copy holds the hand's files (model, assets, licence, README) but not what was computed from the original
(``capture/`` models, ``preview.png``): those belong to the model they were built on. Its ``hand.toml`` is the
original's content with another ``name`` and ``description`` and ``[calibration]`` ``values`` and
``provenance``; it is a hand like any other (a path to it works wherever a hand is named).
"""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import tomli_w

from softsig_service.errors import InvalidInput, InvalidManifest
from softsig_service.hands.manifest import HandManifest, manifest_from_dict

NOT_COPIED = ("capture", "preview.png", "hand.toml")
"""What a variant does not take from the original's folder."""


def variant_manifest(
    manifest: HandManifest,
    name: str,
    values: Mapping[str, float],
    provenance: Mapping[str, Any],
    description: str | None = None,
) -> dict[str, Any]:
    """The variant's manifest as a mapping: the original's fields as written, ``name``, the calibration's values
    and provenance (validated: a value outside its declared range raises :class:`InvalidInput`)."""
    if manifest.calibration is None:
        raise InvalidInput("the hand declares no calibration parameters", field="hand", value=manifest.name)
    data = manifest.model_dump(mode="json", exclude_unset=True)
    data["name"] = name
    data["description"] = description or f"{manifest.description} (calibrated: {dict(values)})"
    cal = dict(data["calibration"])
    cal["values"] = {k: float(v) for k, v in values.items()}
    cal["provenance"] = _without_none(dict(provenance))
    data["calibration"] = cal
    try:
        manifest_from_dict(data, source=f"{name}/hand.toml")
    except InvalidManifest as exc:  # it names the manifest's field; here it is a value the caller chose
        raise InvalidInput(exc.message, field=exc.field, value=exc.value) from None
    return data


def _without_none(value: Any) -> Any:
    """``value`` with every None left out (TOML has no null)."""
    if isinstance(value, Mapping):
        return {str(k): _without_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple):
        return [_without_none(v) for v in value if v is not None]
    return value


def write_variant(
    original_folder: Path,
    manifest: HandManifest,
    out_folder: Path,
    name: str,
    values: Mapping[str, float],
    provenance: Mapping[str, Any],
    description: str | None = None,
) -> Path:
    """Write the variant into ``out_folder`` (created; must not exist or be empty) and return its ``hand.toml``."""
    data = variant_manifest(manifest, name, values, provenance, description)
    out_folder.mkdir(parents=True, exist_ok=True)
    if any(out_folder.iterdir()):
        raise InvalidInput("the variant's folder is not empty", field="out", value=str(out_folder))
    for item in original_folder.iterdir():
        if item.name in NOT_COPIED:
            continue
        if item.is_dir():
            shutil.copytree(item, out_folder / item.name)
        else:
            shutil.copy2(item, out_folder / item.name)
    path = out_folder / "hand.toml"
    header = f"# {name}: a calibrated variant of {manifest.name} (softsig_service/hands/variant.py)\n"
    path.write_text(header + tomli_w.dumps(data), encoding="utf-8")
    return path
