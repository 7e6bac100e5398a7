"""The small xacro test hand of ``tests/hands/data/mini_hand`` copied into a temporary folder, with manifest edits."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

MINI_HAND = Path(__file__).resolve().parent / "data" / "mini_hand"


def mini_hand(tmp_path: Path, closure: str | None = None, **fields: str) -> Path:
    """A copy of the mini hand under ``tmp_path``; ``closure`` replaces its ``[closure]`` table and every
    keyword replaces (or, with the value ``""``, removes) that top-level manifest line. Returns hand.toml."""
    folder = tmp_path / "mini_hand"
    shutil.copytree(MINI_HAND, folder, ignore=shutil.ignore_patterns(".softsig-cache"))
    toml = folder / "hand.toml"
    text = toml.read_text(encoding="utf-8")
    for key, value in fields.items():
        line = f"{key} = {value}\n" if value else ""
        text = re.sub(rf"^{key} = .*\n", line, text, count=1, flags=re.M)
    if closure is not None:
        text = text[: text.index("[closure]")] + "[closure]\n" + closure.strip() + "\n"
    toml.write_text(text, encoding="utf-8")
    return toml
