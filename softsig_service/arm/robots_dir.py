"""Where example-robot-data's UR5 model files are: the ``robots`` folder that holds ``ur_description``.

The model files are never copied: they are located at run time in the installed example-robot-data package
(``cmeel.prefix/share/example-robot-data/robots``), or in a folder the caller names (the service's setting
``robots_dir``, ``SOFTSIG_ROBOTS_DIR``).
"""

from __future__ import annotations

import contextlib
import os
import site
import sys
from collections.abc import Iterator
from pathlib import Path

URDF_RELATIVE = Path("ur_description/urdf/ur5_robot.urdf")
"""The UR5 URDF, relative to the ``robots`` folder."""
SRDF_RELATIVE = Path("ur_description/srdf/ur5.srdf")
"""The UR5 SRDF (disabled collision pairs), relative to the ``robots`` folder."""


def _candidate_roots() -> Iterator[Path]:
    """Folders that may hold ``cmeel.prefix`` (site-packages of this interpreter, then ``sys.path``)."""
    seen: set[Path] = set()
    roots: list[str] = []
    try:
        import cmeel  # the pip wheels install into <site-packages>/cmeel.prefix

        roots.append(str(Path(cmeel.__file__).resolve().parent.parent))
    except ImportError:  # pragma: no cover - cmeel ships with pin
        pass
    with contextlib.suppress(AttributeError):  # some virtualenv flavours lack it
        roots.extend(site.getsitepackages())
    roots.append(site.getusersitepackages())
    roots.extend(sys.path)
    pyver = f"python{sys.version_info.major}.{sys.version_info.minor}"
    for prefix in (sys.prefix, sys.base_prefix):
        roots.append(os.path.join(prefix, "lib", pyver, "site-packages"))
    for r in roots:
        if not r:
            continue
        p = Path(r).resolve()
        if p not in seen:
            seen.add(p)
            yield p


def find_robots_dir(override: Path | None = None) -> Path:
    """The example-robot-data ``robots`` folder (the one that holds ``ur_description``).

    ``override`` wins when given (and must hold ``ur_description/urdf/ur5_robot.urdf``); otherwise
    ``cmeel.prefix/share/example-robot-data/robots`` is looked up under the site-packages of this interpreter
    and the entries of ``sys.path``. Raises ``FileNotFoundError`` listing what was searched.
    """
    if override is not None:
        p = Path(override).expanduser().resolve()
        if not (p / URDF_RELATIVE).is_file():
            raise FileNotFoundError(f"robots_dir={str(override)!r} does not contain {URDF_RELATIVE}")
        return p
    searched: list[str] = []
    for root in _candidate_roots():
        p = root / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        searched.append(str(p))
        if (p / URDF_RELATIVE).is_file():
            return p
    raise FileNotFoundError(
        "example-robot-data's robots folder was not found (install the 'example-robot-data' package or set "
        f"SOFTSIG_ROBOTS_DIR); searched: {', '.join(searched)}"
    )
