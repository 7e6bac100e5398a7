"""The process that expands one xacro file (``python -m softsig_service.hands.xacro_sandbox``).

Run by :func:`softsig_service.hands.xacro_expand.expand_xacro`, never imported by the service itself. It reads
one JSON request on stdin (``file``, ``folder``, ``args``, ``memory_bytes``, ``cpu_seconds``), limits its own
address space and CPU time (``setrlimit``), then expands the file with the ``xacro`` package under an audit hook
that refuses, while the expansion runs:

* opening a file outside the hand's folder, or opening any file for writing;
* listing a folder outside the hand's folder;
* starting a process (``subprocess``, ``os.system``, ``exec``, ``fork``, ``spawn``), opening a socket, loading a
  shared library through ``ctypes``;
* ``$(env NAME)`` (the environment is not the description's to read; ``$(optenv NAME DEFAULT)`` gives DEFAULT).

``$(find PKG)`` and ``package://PKG/...`` resolve inside the hand's folder: ``$(find PKG)`` is the sub-folder
``PKG`` when the folder has one, else the folder itself. The answer is one JSON object on stdout: ``{"xml": ...,
"files": [...]}`` (the files read, relative to the folder), or ``{"error": KIND, "detail": ..., "value": ...}``
with KIND one of ``read``, ``write``, ``environment``, ``command``, ``network``, ``recursion``, ``memory``,
``xacro``.
"""

from __future__ import annotations

import json
import os
import resource
import sys
from pathlib import Path
from typing import Any

_BLOCKED_EVENTS = {
    "subprocess.Popen": "command",
    "os.system": "command",
    "os.exec": "command",
    "os.posix_spawn": "command",
    "os.spawn": "command",
    "os.fork": "command",
    "os.forkpty": "command",
    "os.kill": "command",
    "pty.spawn": "command",
    "ctypes.dlopen": "command",
    "socket.connect": "network",
    "socket.bind": "network",
    "socket.getaddrinfo": "network",
    "os.remove": "write",
    "os.rename": "write",
    "os.rmdir": "write",
    "os.mkdir": "write",
    "os.chmod": "write",
    "os.symlink": "write",
    "os.link": "write",
    "os.truncate": "write",
    "shutil.rmtree": "write",
}


_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND


class Forbidden(Exception):
    """What the description tried and was refused: ``kind`` and the offending ``value``."""

    def __init__(self, kind: str, detail: str, value: str) -> None:
        super().__init__(f"{detail}: {value}")
        self.kind = kind
        self.detail = detail
        self.value = value


class _Guard:
    """The audit hook: refuses everything in the module docstring once :attr:`armed` is set."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.armed = False
        self.violation: Forbidden | None = None
        self.read: set[str] = set()

    def refuse(self, kind: str, detail: str, value: str) -> None:
        exc = Forbidden(kind, detail, value)
        if self.violation is None:
            self.violation = exc  # kept even when xacro wraps the exception into its own
        raise exc

    def _inside(self, path: Any) -> Path | None:
        if isinstance(path, int):
            return self.folder  # an open file descriptor: already checked when it was opened
        resolved = Path(os.fsdecode(path)).resolve()
        return resolved if resolved.is_relative_to(self.folder) else None

    def __call__(self, event: str, args: tuple[Any, ...]) -> None:
        if not self.armed:
            return
        if event == "open":
            path, mode = args[0], args[1]
            if path is None:
                return
            inside = self._inside(path)
            if inside is None:
                self.refuse("read", "the description reads a file outside the hand's folder", os.fsdecode(path))
            flags = args[2] if len(args) > 2 and isinstance(args[2], int) else 0
            if (isinstance(mode, str) and any(c in mode for c in "wax+")) or flags & _WRITE_FLAGS:
                self.refuse("write", "the description writes a file", os.fsdecode(path))
            if inside is not None and inside != self.folder:
                self.read.add(inside.relative_to(self.folder).as_posix())
        elif event in ("os.listdir", "os.scandir"):
            if args and args[0] is not None and self._inside(args[0]) is None:
                self.refuse("read", "the description lists a folder outside the hand's folder", str(args[0]))
        elif event in _BLOCKED_EVENTS or event.split(".")[0] in ("subprocess", "socket"):
            kind = _BLOCKED_EVENTS.get(event, event.split(".")[0].replace("subprocess", "command"))
            what = {"command": "runs a command", "network": "opens a network connection", "write": "changes files"}
            self.refuse(kind, f"the description {what.get(kind, 'does ' + event)}", f"{event} {_short(args)}")


def _short(args: tuple[Any, ...]) -> str:
    text = repr(args)
    return text if len(text) <= 200 else text[:200] + "..."


def _is_banner(text: str) -> bool:
    return "autogenerated by xacro" in text or "EDITING THIS FILE" in text or not text.strip(" =")


def _causes(exc: BaseException) -> list[BaseException]:
    """``exc`` and what it wraps (xacro's ``exc`` attribute, ``__cause__``, ``__context__``), at most 50 deep."""
    out: list[BaseException] = []
    todo: list[BaseException | None] = [exc]
    while todo and len(out) < 50:
        e = todo.pop()
        if e is None or any(e is o for o in out):
            continue
        out.append(e)
        inner = getattr(e, "exc", None)
        todo += [inner if isinstance(inner, BaseException) else None, e.__cause__, e.__context__]
    return out


def _patch_xacro(folder: Path, guard: _Guard) -> Any:
    import xacro
    import xacro.substitution_args as subst

    def find(pkg: str) -> str:
        sub = (folder / pkg).resolve()
        return str(sub) if sub.is_dir() and sub.is_relative_to(folder) else str(folder)

    def env(name: str) -> str:
        guard.refuse("environment", "the description reads an environment variable", name)
        return ""

    def optenv(name: str, default: str = "") -> str:
        return default

    subst._eval_find = find
    subst._eval_env = env
    subst._eval_optenv = optenv
    subst._eval_dict.update(find=find, env=env, optenv=optenv)
    xacro.root_dir = str(folder)
    return xacro


def expand(request: dict[str, Any]) -> dict[str, Any]:
    """Expand the request's file; the answer described in the module docstring."""
    folder = Path(request["folder"]).resolve()
    file = Path(request["file"]).resolve()
    guard = _Guard(folder)
    xacro = _patch_xacro(folder, guard)
    import xml.dom.expatbuilder  # (imported lazily by minidom: load it before the guard is armed)
    import xml.parsers.expat

    import yaml  # noqa: F401  (likewise, for xacro.load_yaml)

    warm = '<robot xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="a" value="${1 + 1}"/></robot>'
    xacro.process_doc(xacro.parse(warm))  # any other lazy import happens here, before the guard is armed

    sys.addaudithook(guard)
    mem = int(request["memory_bytes"])
    resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
    cpu = max(1, int(request["cpu_seconds"]))
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 1))
    guard.armed = True
    try:
        doc = xacro.process_file(str(file), mappings=dict(request["args"]))
        for node in list(doc.childNodes):  # xacro's banner names the absolute path: keep the text path-free
            if node.nodeType == node.COMMENT_NODE and _is_banner(node.data):
                doc.removeChild(node)
        text = doc.toprettyxml(indent="  ")
    except Exception as exc:  # xacro wraps what went wrong into its own exception: look for the cause
        guard.armed = False
        if guard.violation is not None:
            v = guard.violation
            return {"error": v.kind, "detail": v.detail, "value": v.value}
        causes = _causes(exc)
        if any(isinstance(c, RecursionError) for c in causes):
            return {"error": "recursion", "detail": "the expansion recurses without end", "value": file.name}
        if any(isinstance(c, MemoryError) for c in causes):
            return {"error": "memory", "detail": "the expansion exceeds the memory limit", "value": mem}
        detail = f"{type(exc).__name__}: {exc}".strip()
        if isinstance(exc, xml.parsers.expat.ExpatError):
            detail = f"not well-formed XML: {exc}"
        return {"error": "xacro", "detail": detail, "value": file.name}
    guard.armed = False
    if guard.violation is not None:
        v = guard.violation
        return {"error": v.kind, "detail": v.detail, "value": v.value}
    return {"xml": text, "files": sorted(guard.read)}


def main() -> None:
    """Read the request from stdin, write the answer to stdout."""
    request = json.loads(sys.stdin.read())
    answer = expand(request)
    sys.stdout.write(json.dumps(answer))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
