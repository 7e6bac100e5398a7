"""Request and response bodies of the object registry (``/v1/objects``).

Same conventions as :mod:`softsig_service.api.schemas` (strict requests, closed responses, SI units, ``base_link``).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from pydantic import Field

from softsig_service.api.schemas import Out, Vector3
from softsig_service.objects.schema import ObjectSpec, SceneFields


class ObjectIn(SceneFields):
    """An object to register, as any object JSON (a cloud in a camera frame with ``frames``; not a stored one), on the
    table at ``table.height``; ``name`` labels it (default: the object's own)."""

    object: ObjectSpec
    name: str = Field("", max_length=64)


class ObjectOut(Out):
    """A registered object: its ``id`` (``{"kind": "stored", "id": ...}`` in plans and validations), ``name``, the
    ``source`` it was made from (a kind, or a file type), ``object`` its JSON as the planner takes it (a cloud's
    solid as a mesh) at the pose it was registered at, ``table_height`` [m], and what the planner derives from it:
    the principal horizontal axes ``o1``, ``o2`` and extents [m], its ``height`` [m]."""

    id: str
    name: str
    source: str
    object: dict[str, Any]
    table_height: float
    o1: Vector3
    o2: Vector3
    extent_major: float
    extent_minor: float
    height: float
    created_at: datetime
    links: dict[str, str]


class ObjectSummary(Out):
    """A registered object in a list (without its geometry)."""

    id: str
    name: str
    source: str
    created_at: datetime
    links: dict[str, str]


class ObjectList(Out):
    """A page of registered objects, newest first."""

    items: list[ObjectSummary]
    total: int
    limit: int
    offset: int
