"""Reference-point trajectories of a closing hand, and their JSON form.

A :class:`ClosureTrajectory` holds ``positions[t, i, :]``: the position [m] of reference point ``i`` at sample
``t``, expressed in the hand frame (origin at the flange, +z = approach, +x across the palm; docs/design.md §3), with
the sample times ``times[t]`` [s] starting at the open hand (t = 0) and ending at the closed hand (t = T-1).
``surface`` optionally holds a dense set of hand-surface points tracked the same way (for the mesh method).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import InvalidTrajectory

MIN_POINTS = 4
"""Fewest reference points a closure signature can be computed from."""


@dataclass(frozen=True)
class ClosureTrajectory:
    """Tracked reference points of one closure, in the hand frame [m], sampled at ``times`` [s]."""

    hand: str
    times: NDArray[np.float64]
    point_names: tuple[str, ...]
    positions: NDArray[np.float64]
    frame_id: str = "hand"
    surface: NDArray[np.float64] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        validate_trajectory(self.times, self.point_names, self.positions)
        if self.surface is not None:
            s = self.surface
            if s.ndim != 3 or s.shape[0] != self.times.shape[0] or s.shape[2] != 3:
                raise InvalidTrajectory(
                    "surface must have shape (T, M, 3) with the same T as times",
                    field="surface",
                    value=s.shape,
                )
            if not np.all(np.isfinite(s)):
                raise InvalidTrajectory("surface points must be finite", field="surface")

    @property
    def n_frames(self) -> int:
        """Number of samples T."""
        return int(self.times.shape[0])

    @property
    def n_points(self) -> int:
        """Number of reference points N."""
        return len(self.point_names)

    def to_json_dict(self) -> dict[str, Any]:
        """The trajectory JSON of ``softsig hands close``: hand, frame_id, times, point_names, positions [m]."""
        return {
            "hand": self.hand,
            "frame_id": self.frame_id,
            "times": [float(t) for t in self.times],
            "point_names": list(self.point_names),
            "positions": self.positions.tolist(),
        }

    @classmethod
    def from_json_dict(cls, data: Any) -> ClosureTrajectory:
        """Parse the trajectory JSON (see :meth:`to_json_dict`); raise :class:`InvalidTrajectory` naming the field."""
        if not isinstance(data, dict):
            raise InvalidTrajectory("trajectory JSON must be an object", field="$", value=type(data).__name__)
        required = ("times", "point_names", "positions")
        for key in required:
            if key not in data:
                raise InvalidTrajectory(f"missing key {key!r}", field=key, choices=required)
        frame_id = data.get("frame_id", "hand")
        if frame_id != "hand":
            raise InvalidTrajectory(
                "trajectories must be expressed in the hand frame",
                field="frame_id",
                value=frame_id,
                choices=["hand"],
            )
        names = data["point_names"]
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise InvalidTrajectory("point_names must be a list of strings", field="point_names")
        try:
            times = np.asarray(data["times"], dtype=np.float64)
        except (TypeError, ValueError, RecursionError) as exc:
            raise InvalidTrajectory("times must be a list of numbers", field="times") from exc
        try:
            positions = np.asarray(data["positions"], dtype=np.float64)
        except (TypeError, ValueError, RecursionError) as exc:
            raise InvalidTrajectory(
                "positions must be a [T][N][3] array of numbers (ragged or non-numeric data found)",
                field="positions",
            ) from exc
        return cls(
            hand=str(data.get("hand", "markers")),
            times=times,
            point_names=tuple(names),
            positions=positions,
            frame_id="hand",
        )


def validate_trajectory(
    times: NDArray[np.float64], point_names: tuple[str, ...], positions: NDArray[np.float64]
) -> None:
    """Check shapes, finiteness, monotone times, unique names and N >= 4; raise :class:`InvalidTrajectory`."""
    if times.ndim != 1 or times.shape[0] < 2:
        raise InvalidTrajectory("times must be a 1-D list of at least 2 samples", field="times", value=times.shape)
    if not np.all(np.isfinite(times)):
        raise InvalidTrajectory("times must be finite (no NaN or infinity)", field="times")
    if np.any(np.diff(times) <= 0):
        bad = int(np.argmax(np.diff(times) <= 0)) + 1
        raise InvalidTrajectory("times must be strictly increasing", field=f"times[{bad}]", value=float(times[bad]))
    if len(set(point_names)) != len(point_names):
        dup = sorted({n for n in point_names if point_names.count(n) > 1})
        raise InvalidTrajectory("point names must be unique", field="point_names", value=dup)
    if len(point_names) < MIN_POINTS:
        raise InvalidTrajectory(
            f"at least {MIN_POINTS} reference points are needed", field="point_names", value=len(point_names)
        )
    expected = (times.shape[0], len(point_names), 3)
    if positions.shape != expected:
        raise InvalidTrajectory(
            f"positions must have shape [T][N][3] = {list(expected)}",
            field="positions",
            value=list(positions.shape),
        )
    finite = np.isfinite(positions)
    if not np.all(finite):
        t, i, _ = (int(v) for v in np.argwhere(~finite)[0])
        raise InvalidTrajectory(
            "positions must be finite (no NaN or infinity)",
            field=f"positions[{t}][{i}]",
            value=[None if not math.isfinite(v) else float(v) for v in positions[t, i]],
        )
