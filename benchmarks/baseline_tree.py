"""An earlier revision of this repository, exported beside the working tree, for the benchmarks' ``--baseline``.

A process runs the exported package only if it starts with the exported folder as its working directory and on
``PYTHONPATH``: ``python -m`` and ``python -c`` put the working directory first on ``sys.path``, ahead of
``PYTHONPATH``, and the working tree's package is also installed in editable mode.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
"""The working tree (this repository's root)."""


def export_revision(revision: str, dest: Path) -> Path:
    """The tree of git revision ``revision`` (``git archive``) in the new folder ``dest/tree``; that folder."""
    root = dest / "tree"
    root.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", revision], check=True, capture_output=True)
    subprocess.run(["tar", "-x", "-C", str(root)], input=archive.stdout, check=True)
    return root


def tree_env(root: Path | None) -> tuple[dict[str, str], str]:
    """(environment, working directory) that make a child process import the package of ``root`` (None: the
    working tree)."""
    tree = root or ROOT
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree) + os.pathsep + env.get("PYTHONPATH", "")
    return env, str(tree)
