"""Errors of pydantic validation as softsig names them: the dotted path of the offending field and, for closed
sets, the valid choices. Shared by the REST API's problem bodies and the object parser.
"""

from __future__ import annotations

import re
from collections.abc import Collection, Mapping, Sequence
from typing import Any

from pydantic import ValidationError

from softsig_service.errors import InvalidInput

LOCATIONS = ("body", "query", "path", "header", "cookie")
"""The first element of a FastAPI error location names where the value came from."""


def field_path(loc: Sequence[int | str], tags: Collection[str] = ()) -> tuple[str, str]:
    """(location, dotted field path) of a pydantic/FastAPI error location.

    ``("body", "object", "box", "size", 2)`` -> ``("body", "object.size[2]")``: the location (body, query, path,
    header) is split off and discriminator ``tags`` are left out. The body itself is ``"$"``.
    """
    parts = list(loc)
    where = str(parts.pop(0)) if parts and parts[0] in LOCATIONS else "body"
    out = ""
    after_tag = False  # a tag is followed by a field of its member, which may share its name ("points")
    for k, part in enumerate(parts):
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in tags and not after_tag and k < len(parts) - 1:
            after_tag = True
            continue
        else:
            out += ("." if out else "") + str(part)
        after_tag = False
    return where, out or "$"


def error_choices(err: Mapping[str, Any]) -> list[str] | None:
    """The valid values a pydantic error lists (a literal's or a discriminator's), sorted; None if it has none."""
    ctx = err.get("ctx") or {}
    for key in ("expected", "expected_tags"):
        if key in ctx:
            found = re.findall(r"'([^']*)'", str(ctx[key]))
            if found:
                return sorted(found)
    return None


def invalid_input(exc: ValidationError, root: str, tags: Collection[str] = ()) -> InvalidInput:
    """The first error of ``exc`` as :class:`InvalidInput`, its field prefixed with ``root`` (e.g. ``object``; ""
    names the field from the validated document's top)."""
    err = exc.errors()[0]
    _, path = field_path(tuple(err.get("loc", ())), tags)
    if root:
        path = root if path == "$" else f"{root}.{path}" if not path.startswith("[") else f"{root}{path}"
    value = None if err.get("type") == "missing" else err.get("input")
    return InvalidInput(str(err.get("msg", "invalid value")), field=path, value=value, choices=error_choices(err))
