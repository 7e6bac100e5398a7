"""Marker trajectories from CSV and JSON: round trips, ordering, a clear error for every bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from softsig_service.errors import InvalidTrajectory
from softsig_service.hands.trajectory import ClosureTrajectory
from softsig_service.signatures.markers import load_markers, parse_markers_csv, parse_markers_json

NAMES = ("thumb", "index", "middle", "ring", "little", "wrist")


def csv_text(times: NDArray[np.float64], names: tuple[str, ...], positions: NDArray[np.float64]) -> str:
    lines = ["time,point,x,y,z"]
    for ti, t in enumerate(times):
        for pi, name in enumerate(names):
            x, y, z = (float(v) for v in positions[ti, pi])
            lines.append(f"{float(t)!r},{name},{x!r},{y!r},{z!r}")
    return "\n".join(lines) + "\n"


def small_csv() -> str:
    rng = np.random.default_rng(0)
    return csv_text(np.array([0.0, 0.1, 0.2]), NAMES[:4], rng.normal(size=(3, 4, 3)))


@settings(max_examples=30, deadline=None)
@given(
    n_frames=st.integers(2, 6),
    n_points=st.integers(4, 6),
    seed=st.integers(0, 2**32 - 1),
    shuffle=st.booleans(),
)
def test_csv_round_trip(n_frames: int, n_points: int, seed: int, shuffle: bool) -> None:
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.001, 0.1, size=n_frames))
    names = NAMES[:n_points]
    positions = rng.normal(scale=0.05, size=(n_frames, n_points, 3))
    header, *rows = csv_text(times, names, positions).splitlines()
    if shuffle:  # rows in any order: times are sorted, but the first row names the first point
        first, rest = rows[0], rows[1:]
        rest = [rest[i] for i in rng.permutation(len(rest))]
        rows = [first, *rest]
    traj = parse_markers_csv("\n".join([header, *rows]), hand="sdm")
    assert traj.hand == "sdm"
    assert traj.frame_id == "hand"
    assert traj.point_names[0] == names[0]
    assert sorted(traj.point_names) == sorted(names)
    np.testing.assert_array_equal(traj.times, times)
    order = [names.index(n) for n in traj.point_names]
    np.testing.assert_array_equal(traj.positions, positions[:, order])


def test_points_are_ordered_by_first_appearance_and_times_sorted() -> None:
    text = "\n".join(
        [
            "point, time , z,y,x",  # any column order, spaces around names
            "wrist,0.5,3,2,1",
            "thumb,0.5,6,5,4",
            "index,0.0,0,0,0",
            "ring,0.5,1,1,1",
            "",
            "index,0.5,9,8,7",
            "wrist,0.0,0,0,0",
            "thumb,0.0,0,0,0",
            "ring,0.0,0,0,0",
        ]
    )
    traj = parse_markers_csv("\ufeff" + text)  # a UTF-8 byte-order mark is accepted
    assert traj.point_names == ("wrist", "thumb", "index", "ring")
    np.testing.assert_array_equal(traj.times, [0.0, 0.5])
    np.testing.assert_array_equal(traj.positions[1, 0], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(traj.positions[1, 2], [7.0, 8.0, 9.0])
    np.testing.assert_array_equal(traj.positions[0], 0.0)
    assert traj.hand == "markers"


def test_json_round_trip() -> None:
    rng = np.random.default_rng(1)
    traj = ClosureTrajectory(
        hand="softhand",
        times=np.array([0.0, 0.5, 1.0]),
        point_names=NAMES,
        positions=rng.normal(size=(3, 6, 3)),
    )
    back = parse_markers_json(json.dumps(traj.to_json_dict()))
    assert back.hand == "softhand"
    assert back.point_names == NAMES
    np.testing.assert_array_equal(back.positions, traj.positions)
    np.testing.assert_array_equal(back.times, traj.times)


def test_load_markers_dispatches_on_the_suffix(tmp_path: Path) -> None:
    text = small_csv()
    (tmp_path / "m.CSV").write_text(text)
    from_csv = load_markers(tmp_path / "m.CSV", hand="rbo")
    assert from_csv.hand == "rbo"
    (tmp_path / "m.json").write_text(json.dumps(from_csv.to_json_dict()))
    from_json = load_markers(tmp_path / "m.json")
    np.testing.assert_array_equal(from_json.positions, from_csv.positions)
    assert from_json.point_names == from_csv.point_names

    (tmp_path / "m.txt").write_text(text)
    with pytest.raises(InvalidTrajectory) as info:
        load_markers(tmp_path / "m.txt")
    assert info.value.field == "path"
    assert info.value.choices == [".csv", ".json"]
    with pytest.raises(InvalidTrajectory, match="not found") as info:
        load_markers(tmp_path / "absent.csv")
    assert info.value.field == "path"
    (tmp_path / "latin1.csv").write_bytes("time,point,x,y,z\n0,pouce\xe9,0,0,0\n".encode("latin-1"))
    with pytest.raises(InvalidTrajectory, match="UTF-8"):
        load_markers(tmp_path / "latin1.csv")


def replace_cell(text: str, row: int, column: int, value: str) -> str:
    """Set the cell at 1-based file row ``row`` and 0-based ``column``."""
    lines = text.splitlines()
    cells = lines[row - 1].split(",")
    cells[column] = value
    lines[row - 1] = ",".join(cells)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    ("row", "column", "value", "field", "match"),
    [
        (5, 2, "nan", "row 5: x", "finite"),
        (7, 3, "NaN", "row 7: y", "finite"),
        (3, 4, "inf", "row 3: z", "finite"),
        (9, 3, "abc", "row 9: y", "not a number"),
        (4, 0, "", "row 4: time", "not a number"),
        (6, 4, "1,5", "row 6", "expected 5 fields"),
        (8, 1, "  ", "row 8: point", "empty"),
    ],
)
def test_bad_cells_name_their_row_and_column(row: int, column: int, value: str, field: str, match: str) -> None:
    with pytest.raises(InvalidTrajectory, match=match) as info:
        parse_markers_csv(replace_cell(small_csv(), row, column, value))
    assert info.value.field == field


def test_a_missing_frame_names_the_point_and_the_time() -> None:
    lines = small_csv().splitlines()
    del lines[7]  # row 8: the third point at the second time
    with pytest.raises(InvalidTrajectory, match=r"'middle' has no row at time 0\.1") as info:
        parse_markers_csv("\n".join(lines))
    assert info.value.field == "time 0.1"
    assert info.value.value == ["middle"]


def test_a_point_seen_at_only_some_times_is_a_missing_frame() -> None:
    text = small_csv() + "0.2,pinky,0,0,0\n"
    with pytest.raises(InvalidTrajectory, match=r"'pinky' has no row at time 0\.0"):
        parse_markers_csv(text)


def test_a_repeated_sample_names_both_rows() -> None:
    text = small_csv() + "0.1,index,0,0,0\n"
    with pytest.raises(InvalidTrajectory, match=r"given twice \(first in row 7\)") as info:
        parse_markers_csv(text)
    assert info.value.field == "row 14"


def test_unknown_and_missing_points_against_the_expected_set() -> None:
    expected = [*NAMES[:3], "little"]
    with pytest.raises(InvalidTrajectory, match="unknown point") as info:
        parse_markers_csv(small_csv(), expected_points=expected)
    assert info.value.field == "row 5: point"
    assert info.value.value == "ring"
    assert info.value.choices == sorted(expected)
    with pytest.raises(InvalidTrajectory, match="missing") as info:
        parse_markers_csv(small_csv(), expected_points=[*NAMES[:4], "wrist"])
    assert info.value.value == ["wrist"]
    traj = parse_markers_csv(small_csv())
    with pytest.raises(InvalidTrajectory, match="unknown point") as info:
        parse_markers_json(json.dumps(traj.to_json_dict()), expected_points=NAMES[:3])
    assert info.value.value == ["ring"]


def test_fewer_than_four_points() -> None:
    rng = np.random.default_rng(2)
    with pytest.raises(InvalidTrajectory, match="at least 4") as info:
        parse_markers_csv(csv_text(np.array([0.0, 1.0]), NAMES[:3], rng.normal(size=(2, 3, 3))))
    assert info.value.value == list(NAMES[:3])


@pytest.mark.parametrize(
    ("text", "field", "match"),
    [
        ("", "header", "empty"),
        ("time,point,x,y\n0,a,0,0\n", "row 1: header", "missing"),
        ("time,point,x,y,z,w\n", "row 1: header", "unexpected"),
        ("time,point,x,y,z,z\n", "row 1: header", "unexpected|repeated"),
        ("time,point,x,y,z\n", "rows", "no data rows"),
    ],
)
def test_bad_headers_and_empty_files(text: str, field: str, match: str) -> None:
    with pytest.raises(InvalidTrajectory, match=match) as info:
        parse_markers_csv(text)
    assert info.value.field == field


def test_a_single_time_is_not_a_closure() -> None:
    rng = np.random.default_rng(3)
    with pytest.raises(InvalidTrajectory, match="at least 2 samples"):
        parse_markers_csv(csv_text(np.array([0.0]), NAMES, rng.normal(size=(1, 6, 3))))


@pytest.mark.parametrize(
    ("data", "field"),
    [
        ("{not json", "$"),
        ('{"times": [0, 1], "point_names": ["a", "b", "c", "d"]}', "positions"),
        ('{"times": [0, 1], "point_names": ["a", "b", "c", "d"], "positions": [[[0, 0, 0]]]}', "positions"),
        ('{"times": [0, 1], "point_names": ["a","b","c","d"], "positions": [[["x",0,0]]]}', "positions"),
    ],
)
def test_bad_json(data: str, field: str) -> None:
    with pytest.raises(InvalidTrajectory) as info:
        parse_markers_json(data)
    assert info.value.field == field


def test_nan_in_json_names_the_sample() -> None:
    traj = parse_markers_csv(small_csv())
    data = traj.to_json_dict()
    data["positions"][2][1][0] = float("nan")
    with pytest.raises(InvalidTrajectory, match="finite") as info:
        parse_markers_json(json.dumps(data))
    assert info.value.field == "positions[2][1]"
