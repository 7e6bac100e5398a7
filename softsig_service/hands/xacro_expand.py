"""Expansion of a ``.urdf.xacro`` hand description into URDF, in a separate, limited process, with a cache.

A hand's ``model`` may be a xacro file (the ``xacro`` package of PyPI, no ROS needed). It is expanded by
:mod:`softsig_service.hands.xacro_sandbox` in a child process with a clean environment, the hand's folder as its
working directory, an address-space limit (``ModelLimits.xacro_memory_bytes``) and a CPU and wall-time limit
(``ModelLimits.xacro_seconds``); the child refuses to read outside the folder, to write, to open sockets and to
run commands. ``$(find PKG)`` and ``package://PKG/...`` resolve inside the hand's folder; the manifest's
``xacro_args`` set ``<xacro:arg>`` values.

What a refused description gets: :class:`~softsig_service.errors.UnsafeDescription` (reads outside the folder,
reads the environment, writes, opens a connection, runs a command) or
:class:`~softsig_service.errors.ExpansionLimit` (no end within the time, memory or recursion limit), both naming
the problem and the offending path or call; a xacro that is simply wrong gets
:class:`~softsig_service.errors.InvalidHandModel` with xacro's message.

The expanded URDF is cached by the SHA-256 of everything it can depend on (the xacro arguments, the version of
the ``xacro`` package and every file of the hand's folder up to the model-size limit), in memory and on disk in
``<folder>/.softsig-cache/``; :class:`ExpandedUrdf` carries the SHA-256 of the expanded text, which is stored
with the hand (``hand_info``'s ``expanded_urdf``).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

import softsig_service
from softsig_service.config import ModelLimits
from softsig_service.errors import ExpansionLimit, InvalidHandModel, UnsafeDescription

CACHE_DIR = ".softsig-cache"
"""Folder inside a hand's folder that holds its expanded URDFs (never part of an upload)."""

_MEMORY: dict[str, ExpandedUrdf] = {}


@dataclass(frozen=True)
class ExpandedUrdf:
    """The URDF text a xacro expanded to, its SHA-256, the cache key, and the files the expansion read."""

    xml: str
    sha256: str
    key: str
    files: tuple[str, ...]


def cache_key(file: Path, folder: Path, args: Mapping[str, str], limits: ModelLimits) -> str:
    """SHA-256 over the xacro arguments, the xacro version, the file's path and every small file of ``folder``."""
    h = hashlib.sha256()
    h.update(json.dumps({"args": dict(sorted(args.items())), "xacro": version("xacro")}).encode())
    h.update(file.relative_to(folder).as_posix().encode())
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder)
        if rel.parts[0] == CACHE_DIR or not path.is_file() or path.is_symlink():
            continue
        if path.stat().st_size <= limits.max_model_bytes:
            h.update(rel.as_posix().encode() + b"\0" + hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()


def expand_xacro(file: Path, folder: Path, args: Mapping[str, str], limits: ModelLimits) -> ExpandedUrdf:
    """The URDF ``file`` (a xacro inside ``folder``) expands to with ``args``; cached (module docstring)."""
    folder = folder.resolve()
    file = file.resolve()
    key = cache_key(file, folder, args, limits)
    hit = _MEMORY.get(key) or _read_cache(folder, key)
    if hit is None:
        hit = _run_sandbox(file, folder, args, limits, key)
        _write_cache(folder, hit)
    _MEMORY[key] = hit
    return hit


def _read_cache(folder: Path, key: str) -> ExpandedUrdf | None:
    path = folder / CACHE_DIR / f"{key}.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        xml = str(data["xml"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if hashlib.sha256(xml.encode()).hexdigest() != data.get("sha256"):
        return None
    return ExpandedUrdf(xml=xml, sha256=data["sha256"], key=key, files=tuple(data.get("files", ())))


def _write_cache(folder: Path, exp: ExpandedUrdf) -> None:
    """Best effort: a read-only folder just means the next process expands again."""
    try:
        (folder / CACHE_DIR).mkdir(exist_ok=True)
        data = {"xml": exp.xml, "sha256": exp.sha256, "files": list(exp.files)}
        tmp = folder / CACHE_DIR / f"{exp.key}.{os.getpid()}.tmp"  # one per process: concurrent loads race
        tmp.write_text(json.dumps(data), encoding="utf-8")
        tmp.replace(folder / CACHE_DIR / f"{exp.key}.json")
    except OSError:
        pass


_UNSAFE = {"read", "write", "environment", "command", "network"}


def _run_sandbox(file: Path, folder: Path, args: Mapping[str, str], limits: ModelLimits, key: str) -> ExpandedUrdf:
    request = {
        "file": str(file),
        "folder": str(folder),
        "args": {str(k): str(v) for k, v in args.items()},
        "memory_bytes": limits.xacro_memory_bytes,
        "cpu_seconds": limits.xacro_seconds,
    }
    package_root = str(Path(softsig_service.__file__).resolve().parent.parent)
    env = {"PYTHONPATH": package_root, "PATH": "/usr/bin:/bin", "LC_ALL": "C.UTF-8"}
    cmd = [sys.executable, "-m", "softsig_service.hands.xacro_sandbox"]
    try:
        proc = subprocess.run(
            cmd, input=json.dumps(request), capture_output=True, text=True, timeout=limits.xacro_seconds,
            cwd=folder, env=env, check=False,
        )  # fmt: skip
    except subprocess.TimeoutExpired:
        raise ExpansionLimit(
            f"the xacro expansion did not finish within {limits.xacro_seconds:g} s (does it expand without end?)",
            field="model",
            value=file.name,
        ) from None
    try:
        answer = json.loads(proc.stdout)
    except ValueError:
        answer = None
    if not isinstance(answer, dict):
        if proc.returncode < 0:  # killed: SIGXCPU at the CPU limit, SIGKILL/SIGSEGV when memory ran out
            raise ExpansionLimit(
                f"the xacro expansion was stopped by its time or memory limit (signal {-proc.returncode})",
                field="model",
                value=file.name,
            )
        tail = proc.stderr.strip().splitlines()[-1:] or ["no output"]
        raise InvalidHandModel(f"the xacro expansion failed: {tail[0]}", field="model", value=file.name)
    if "error" in answer:
        kind = str(answer["error"])
        message = f"{answer.get('detail', 'refused')} (xacro {kind})"
        if kind in _UNSAFE:
            raise UnsafeDescription(message, field="model", value=answer.get("value"))
        if kind in ("recursion", "memory"):
            raise ExpansionLimit(message, field="model", value=answer.get("value"))
        raise InvalidHandModel(f"the xacro could not be expanded: {answer.get('detail')}", field="model",
                               value=answer.get("value"))  # fmt: skip
    xml = str(answer["xml"])
    return ExpandedUrdf(
        xml=xml, sha256=hashlib.sha256(xml.encode()).hexdigest(), key=key, files=tuple(answer.get("files", ()))
    )
