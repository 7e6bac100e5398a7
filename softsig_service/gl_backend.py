"""Choose MuJoCo's OpenGL backend before MuJoCo is imported, and survive a backend that cannot load.

MuJoCo picks its offscreen backend from ``MUJOCO_GL`` when the ``mujoco`` package is first imported, and
an unusable backend (say ``osmesa`` without libOSMesa) makes that import fail for every command, rendering
or not. :func:`prepare_mujoco` defaults the backend to EGL (headless, no display needed), and if the
import still fails, imports MuJoCo with rendering disabled and keeps the reason for
:func:`render_unavailable_reason`.
"""

from __future__ import annotations

import os
import sys

_REASON: str | None = None


def prepare_mujoco(default_backend: str = "egl") -> None:
    """Import MuJoCo with ``MUJOCO_GL`` defaulted to ``default_backend``; fall back to no rendering."""
    global _REASON
    if "mujoco" in sys.modules:
        return
    os.environ.setdefault("MUJOCO_GL", default_backend)
    try:
        import mujoco
    except Exception as exc:  # a broken GL backend raises RuntimeError/AttributeError/OSError at import
        _REASON = f"MUJOCO_GL={os.environ.get('MUJOCO_GL')!r} could not be loaded ({type(exc).__name__}: {exc})"
        for name in [n for n in sys.modules if n.split(".")[0] in ("mujoco", "OpenGL")]:
            del sys.modules[name]
        os.environ["MUJOCO_GL"] = "disable"
        import mujoco  # noqa: F401


def render_unavailable_reason() -> str | None:
    """Why rendering was disabled at import, or ``None`` if the chosen backend loaded."""
    return _REASON
