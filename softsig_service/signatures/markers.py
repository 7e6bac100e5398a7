"""Load tracked marker trajectories (uploaded reference points) as a :class:`ClosureTrajectory`.

Two formats, both in the *hand frame* with positions in metres and times in seconds:

* CSV with the header ``time,point,x,y,z`` (columns in any order, no others) and one row per point and sample:
  ``time`` [s], ``point`` (a name), ``x, y, z`` [m]. Every point must appear exactly once at every time.
  Points are ordered by first appearance in the file, times ascending (rows may come in any order). Blank
  lines are skipped; a UTF-8 byte-order mark is accepted.
* The trajectory JSON of ``softsig hands close`` (:meth:`ClosureTrajectory.to_json_dict`).

Every problem raises :class:`InvalidTrajectory` naming where it is: ``field="row 17: x"`` (rows are the file's
1-based line numbers, the header being row 1), ``"header"``, ``"time 0.25"`` for a missing sample,
``"path"``...
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from softsig_service.errors import InvalidTrajectory
from softsig_service.hands.trajectory import MIN_POINTS, ClosureTrajectory

if TYPE_CHECKING:
    from _csv import Reader

CSV_COLUMNS: tuple[str, ...] = ("time", "point", "x", "y", "z")
MAX_ROWS = 100_000
"""Data rows of a marker CSV at the most (a closure of 1,000 samples of 100 points)."""
MAX_POINTS = 256
"""Distinct point names of a marker file at the most."""
MAX_JSON_DEPTH = 32
"""Nesting of a marker JSON at the most (a trajectory needs 4)."""
MAX_CELL_CHARS = 1_000
"""Characters of one CSV cell at the most."""
SUFFIXES: tuple[str, ...] = (".csv", ".json")


def load_markers(
    path: Path, *, hand: str = "markers", expected_points: Sequence[str] | None = None
) -> ClosureTrajectory:
    """Read a marker file, dispatching on its suffix (.csv or .json, case-insensitive).

    ``hand`` names the hand of a CSV file (a JSON file carries its own). With ``expected_points`` (e.g. the
    reference points of a hand manifest) a point not in it, or one of it missing, is an error.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise InvalidTrajectory("unsupported marker file type", field="path", value=path.suffix, choices=SUFFIXES)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError as exc:
        raise InvalidTrajectory("marker file not found", field="path", value=str(path)) from exc
    except UnicodeDecodeError as exc:
        raise InvalidTrajectory("marker file is not UTF-8 text", field="path", value=str(path)) from exc
    except OSError as exc:
        raise InvalidTrajectory(f"cannot read marker file: {exc.strerror}", field="path", value=str(path)) from exc
    if suffix == ".csv":
        return parse_markers_csv(text, hand=hand, expected_points=expected_points)
    return parse_markers_json(text, expected_points=expected_points)


def parse_markers_csv(
    text: str, hand: str = "markers", *, expected_points: Sequence[str] | None = None
) -> ClosureTrajectory:
    """Parse marker CSV text (see the module docstring) into a :class:`ClosureTrajectory` of hand ``hand``."""
    text = text.removeprefix("\ufeff")
    reader = csv.reader(io.StringIO(text))
    try:
        return _parse_rows(reader, hand, expected_points)
    except csv.Error as exc:
        raise InvalidTrajectory(f"malformed CSV: {exc}", field=f"row {reader.line_num}") from None


def _parse_rows(reader: Reader, hand: str, expected_points: Sequence[str] | None) -> ClosureTrajectory:
    """The rows of ``reader`` (header first) as a trajectory, streamed row by row within the caps."""
    header = _read_header(reader)
    col = {name: header.index(name) for name in CSV_COLUMNS}
    expected = set(expected_points) if expected_points is not None else None

    values: dict[tuple[float, str], tuple[float, float, float]] = {}
    first_row: dict[tuple[float, str], int] = {}
    names: dict[str, None] = {}  # insertion-ordered set: order of first appearance
    times: set[float] = set()
    for cells in reader:
        row = reader.line_num
        if not cells or all(not c.strip() for c in cells):
            continue
        if len(cells) != len(header):
            raise InvalidTrajectory(
                f"expected {len(header)} fields ({','.join(header)})", field=f"row {row}", value=len(cells)
            )
        if len(values) >= MAX_ROWS:
            raise InvalidTrajectory(f"more than {MAX_ROWS} data rows", field="rows", value=row)
        t = _number(cells[col["time"]], row, "time")
        name = cells[col["point"]].strip()
        if len(name) > MAX_CELL_CHARS:
            raise InvalidTrajectory(f"a point name is at most {MAX_CELL_CHARS} characters", field=f"row {row}: point",
                                    value=name)  # fmt: skip
        if name not in names and len(names) >= MAX_POINTS:
            raise InvalidTrajectory(f"more than {MAX_POINTS} points", field=f"row {row}: point", value=name)
        if not name:
            raise InvalidTrajectory("point name is empty", field=f"row {row}: point")
        if expected is not None and name not in expected:
            raise InvalidTrajectory("unknown point", field=f"row {row}: point", value=name, choices=expected_points)
        xyz = (
            _number(cells[col["x"]], row, "x"),
            _number(cells[col["y"]], row, "y"),
            _number(cells[col["z"]], row, "z"),
        )
        key = (t, name)
        if key in values:
            raise InvalidTrajectory(
                f"point {name!r} at time {t!r} s is given twice (first in row {first_row[key]})",
                field=f"row {row}",
            )
        values[key] = xyz
        first_row[key] = row
        names.setdefault(name)
        times.add(t)

    if not values:
        raise InvalidTrajectory("the CSV has no data rows", field="rows")
    point_names = tuple(names)
    if expected_points is not None:
        _check_expected(point_names, expected_points)
    if len(point_names) < MIN_POINTS:
        raise InvalidTrajectory(
            f"at least {MIN_POINTS} reference points are needed", field="point", value=list(point_names)
        )
    sorted_times = sorted(times)
    if len(values) != len(sorted_times) * len(point_names):  # a sample is missing: name the first one
        t, name = next((t, n) for t in sorted_times for n in point_names if (t, n) not in values)
        raise InvalidTrajectory(
            f"point {name!r} has no row at time {t!r} s (every point must appear at every time)",
            field=f"time {t!r}",
            value=[n for n in point_names if (t, n) not in values],
        )
    positions = np.empty((len(sorted_times), len(point_names), 3))
    for ti, t in enumerate(sorted_times):
        for pi, name in enumerate(point_names):
            positions[ti, pi] = values[(t, name)]
    return ClosureTrajectory(
        hand=hand,
        times=np.asarray(sorted_times, dtype=np.float64),
        point_names=point_names,
        positions=positions,
        frame_id="hand",
    )


def parse_markers_json(text: str, *, expected_points: Sequence[str] | None = None) -> ClosureTrajectory:
    """Parse trajectory JSON (as :meth:`ClosureTrajectory.to_json_dict` writes it) into a trajectory."""
    text = text.removeprefix("\ufeff")
    deep = _too_deep(text)
    if deep is not None:
        raise InvalidTrajectory(f"the JSON is nested deeper than {MAX_JSON_DEPTH} levels", field=deep)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidTrajectory(f"invalid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})", field="$") from exc
    except RecursionError:
        raise InvalidTrajectory("the JSON is nested too deeply", field="$") from None
    traj = ClosureTrajectory.from_json_dict(data)
    if expected_points is not None:
        _check_expected(traj.point_names, expected_points)
    return traj


_JSON_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def _too_deep(text: str) -> str | None:
    """Where ``text`` nests deeper than :data:`MAX_JSON_DEPTH` (the top-level key, or ``$``), else None."""
    depth, key, last = 0, "$", ""
    for match in _JSON_TOKENS.finditer(text):
        token = match.group()
        if token[0] == '"':
            last = token
        elif token in "[{":
            if depth == 1 and last:
                key = last[1:-1]
            depth += 1
            if depth > MAX_JSON_DEPTH:
                return key
        else:
            depth -= 1
            if depth == 1:
                key = "$"
        if token[0] != '"' and depth != 1:
            last = ""
    return None


def _read_header(reader: Reader) -> list[str]:
    for cells in reader:
        if not cells or all(not c.strip() for c in cells):
            continue
        header = [c.strip() for c in cells]
        missing = [c for c in CSV_COLUMNS if c not in header]
        extra = [c for c in header if c not in CSV_COLUMNS]
        duplicated = sorted({c for c in header if header.count(c) > 1})
        if missing or extra or duplicated:
            problem = f"missing {missing}" if missing else f"unexpected {extra}" if extra else f"repeated {duplicated}"
            raise InvalidTrajectory(
                f"the CSV header must be time,point,x,y,z ({problem})",
                field=f"row {reader.line_num}: header",
                value=",".join(cells),
                choices=CSV_COLUMNS,
            )
        return header
    raise InvalidTrajectory("the CSV is empty: expected the header time,point,x,y,z", field="header")


def _number(cell: str, row: int, column: str) -> float:
    try:
        value = float(cell)
    except ValueError:
        raise InvalidTrajectory("not a number", field=f"row {row}: {column}", value=cell) from None
    if not math.isfinite(value):
        raise InvalidTrajectory("must be finite (no NaN or infinity)", field=f"row {row}: {column}", value=cell)
    return value


def _check_expected(point_names: Sequence[str], expected_points: Sequence[str]) -> None:
    unknown = [n for n in point_names if n not in set(expected_points)]
    if unknown:
        raise InvalidTrajectory("unknown point", field="point_names", value=unknown, choices=expected_points)
    missing = [n for n in expected_points if n not in set(point_names)]
    if missing:
        raise InvalidTrajectory("expected points are missing", field="point_names", value=missing)
