"""Registered objects: the geometry of an object sent once (a mesh, a point cloud's solid, a primitive), as the
object JSON the planner takes, under a random id."""

from __future__ import annotations

import dataclasses
import uuid
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import insert

from softsig_service.registry.db import Registry
from softsig_service.registry.models import ObjectRow, utcnow
from softsig_service.registry.records import get_record, record_from_row, record_page, row_or_not_found


@dataclass(frozen=True)
class ObjectRecord:
    """A registered object: ``spec`` its object JSON in ``base_link`` (with the pose it was registered at) over the
    table at ``table_height`` [m]; ``source`` what it was made from (``points``, ``stl``, ``box``...)."""

    id: str
    name: str
    source: str
    spec: dict[str, Any]
    table_height: float
    created_at: datetime


_INSERT = insert(ObjectRow)
_FIELDS = tuple(f.name for f in dataclasses.fields(ObjectRecord))


def _object(row: ObjectRow) -> ObjectRecord:
    return record_from_row(ObjectRecord, row)


def add_object(reg: Registry, *, name: str, source: str, spec: dict[str, Any], table_height: float) -> ObjectRecord:
    """Store an object under a new random id."""
    rec = ObjectRecord(uuid.uuid4().hex, name, source, dict(spec), float(table_height), utcnow())
    with reg.write_core() as conn:
        conn.execute(_INSERT, {f: getattr(rec, f) for f in _FIELDS})
    return rec


def get_object(reg: Registry, object_id: str) -> ObjectRecord:
    """The object ``object_id``; :class:`NotFound` if there is none."""
    return get_record(reg, ObjectRow, object_id, _object, field="object_id", what="object")


def list_objects(reg: Registry, *, limit: int = 50, offset: int = 0) -> tuple[list[ObjectRecord], int]:
    """Registered objects, newest first, and the total count."""
    return record_page(reg, ObjectRow, _object, limit=limit, offset=offset)


def delete_object(reg: Registry, object_id: str) -> None:
    """Remove the object ``object_id``; :class:`NotFound` if there is none."""
    with reg.write() as s:
        s.delete(row_or_not_found(s, ObjectRow, object_id, field="object_id", what="object"))
