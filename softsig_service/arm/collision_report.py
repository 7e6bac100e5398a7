"""What a collision check reports: colliding pairs by reason, minimum distances [m], and the checks' margins."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from softsig_service.errors import InvalidInput

FloatArray = NDArray[np.float64]

REASON_TABLE = "collision:table"
REASON_OBJECT = "collision:object"
REASON_SELF = "collision:self"

Category = Literal["table", "object", "self"]
REASON_OF: dict[str, str] = {"table": REASON_TABLE, "object": REASON_OBJECT, "self": REASON_SELF}
CATEGORY_ORDER: tuple[Category, ...] = ("table", "object", "self")

TABLE_NAME = "table"
OBJECT_NAME = "object"
HAND_PREFIX = "hand:"

TABLE_EXCLUDED_LINKS = frozenset({"base_link", "shoulder_link"})
"""Arm links not checked against the table: the base stands on it."""
HAND_ATTACHED_LINKS = frozenset({"wrist_3_link", "ee_link"})
"""Arm links not checked against hand shapes: the hand is bolted to their flange."""


@dataclass(frozen=True)
class CollisionReport:
    """Result of a collision check.

    Attributes:
        in_collision: whether any checked pair is closer than the margin.
        pairs: colliding pairs as (name, name): arm links by link name (``"wrist_2_link"``), hand shapes as
            ``"hand:<name>"``, ``"table"``, ``"object"``.
        reasons: distinct reasons, in the order ``collision:table``, ``collision:object``, ``collision:self``.
        min_distance_table: smallest distance [m] of the checked links/hand shapes to the table (negative:
            penetration depth), or None when not computed.
        min_distance_object: same against the object (None without an object or when not computed).
        min_distance_hand_table: smallest distance [m] of the hand shapes alone to the table (None: no hand
            shape or not computed); the arm's upper arm stays ~0.03 m above the table, so
            ``min_distance_table`` rarely says much about the hand.
        min_distance_hand_object: smallest distance [m] of the hand shapes to the object (None when not
            computed, e.g. with ``ignore_hand_object``).
        waypoint: for a path check, the index of the first colliding configuration (None if free).
        checked: number of configurations checked.
    """

    in_collision: bool
    pairs: list[tuple[str, str]]
    reasons: list[str]
    min_distance_table: float | None = None
    min_distance_object: float | None = None
    min_distance_hand_table: float | None = None
    min_distance_hand_object: float | None = None
    waypoint: int | None = None
    checked: int = 1

    @property
    def reason(self) -> str | None:
        """The first reason (table before object before self), or None when free."""
        return self.reasons[0] if self.reasons else None


# ----------------------------------------------------------------------------------------------------------
# the world
# ----------------------------------------------------------------------------------------------------------


def make_report(
    in_collision: bool,
    hits: list[tuple[str, str]],
    reasons: list[str],
    dmin: Sequence[float | None],
    waypoint: int | None = None,
    checked: int = 1,
) -> CollisionReport:
    return CollisionReport(
        in_collision,
        hits,
        reasons,
        min_distance_table=dmin[0],
        min_distance_object=dmin[1],
        min_distance_hand_table=dmin[2],
        min_distance_hand_object=dmin[3],
        waypoint=waypoint,
        checked=checked,
    )


def min_optional(a: float | None, b: float | None) -> float | None:
    if a is None:
        return b
    if b is None:
        return a
    return min(a, b)


def check_finite(v: float, field: str) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("expected a number", field=field, value=v) from exc
    if not math.isfinite(f):
        raise InvalidInput("NaN or infinite value", field=field, value=v)
    return f


def check_margin(m: float, field: str = "margin") -> float:
    f = check_finite(m, field)
    if f < 0.0:
        raise InvalidInput("a margin must be >= 0 [m]", field=field, value=m)
    return f
