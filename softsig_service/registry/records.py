"""Reading ORM rows into the registry's frozen record dataclasses, and finding a row by key or failing clearly."""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

from sqlalchemy.orm import Session

from softsig_service.errors import NotFound

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
