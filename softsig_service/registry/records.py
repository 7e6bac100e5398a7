"""Reading ORM rows into the registry's frozen record dataclasses: one row by key (or a clear NotFound), a page of
rows newest first, and inserting a row."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from softsig_service.errors import NotFound

if TYPE_CHECKING:
    from softsig_service.registry.db import Registry

R = TypeVar("R")
Row = TypeVar("Row")


def record_from_row(record_type: type[R], row: object, **values: Any) -> R:
    """A ``record_type`` dataclass whose fields are read from the same-named attributes of ``row``, except those
    given in ``values``. JSON values (dicts, lists) are copied, so a record's containers are not the session's."""
    for field in dataclasses.fields(record_type):  # type: ignore[arg-type]
        if field.name not in values:
            value = getattr(row, field.name)
            values[field.name] = type(value)(value) if isinstance(value, dict | list) else value
    return record_type(**values)


def row_or_not_found(session: Session, row_type: type[Row], key: str, *, field: str, what: str) -> Row:
    """The row of ``row_type`` with primary key ``key``; :class:`NotFound` ("no such <what>", naming ``field``)
    if there is none."""
    row = session.get(row_type, key)
    if row is None:
        raise NotFound(f"no such {what}", field=field, value=key)
    return row


def get_record(reg: Registry, row_type: type[Row], key: str, record: Callable[[Row], R], *, field: str, what: str) -> R:
    """``record(row)`` of the row of ``row_type`` with primary key ``key``, read in its own transaction;
    :class:`NotFound` as :func:`row_or_not_found` if there is none."""
    with reg.read() as s:
        return record(row_or_not_found(s, row_type, key, field=field, what=what))


def inserted(session: Session, row: Row) -> Row:
    """``row`` added to ``session`` and flushed (its defaults, e.g. ``created_at``, filled in)."""
    session.add(row)
    session.flush()
    return row


def record_page(
    reg: Registry, row_type: type[Any], record: Callable[[Any], R], *, limit: int, offset: int, **equal: Any
) -> tuple[list[R], int]:
    """One page of the rows of ``row_type`` whose columns equal the ``equal`` values (a None value filters nothing),
    newest first (``created_at``, then ``id``), as ``record(row)``, and how many rows match in all."""
    conditions = [getattr(row_type, column) == value for column, value in equal.items() if value is not None]
    order = (row_type.created_at.desc(), row_type.id)
    with reg.read() as s:
        rows = s.scalars(select(row_type).where(*conditions).order_by(*order).limit(limit).offset(offset)).all()
        total = s.execute(select(func.count()).select_from(row_type).where(*conditions)).scalar_one()
        return [record(r) for r in rows], int(total)
