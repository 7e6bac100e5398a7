"""Real grasp outcomes of a hand, as a user measured them: per-cell counts or per-trial records.

A **cell** is what the paper's Table I counts: an object, a strategy, the pose noise the trials were run under
(``sigma_r`` [rad] on the yaw, ``sigma_t`` [m] on x and y, as a campaign's conditions) and ``successes`` out of
``trials``. A **trial record** is one real trial: the same cell fields, its ``success`` and, if it was measured,
the object's ``offset`` from the pose it was planned for (``d_yaw`` [rad], ``dx``, ``dy`` [m] in the table frame):
a calibration simulates that offset instead of drawing one. Objects are the built-in names; strategies the
planner's. Every bad value raises :class:`InvalidInput` naming the field (``cells[2].successes``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator, model_validator

from softsig_service.validation import invalid_input

MAX_SIGMA_R = math.pi
"""[rad] the largest yaw noise a cell may state."""
MAX_SIGMA_T = 0.2
"""[m] the largest position noise a cell may state."""

CellKey = tuple[str, str, float, float]
"""(object, strategy, sigma_r, sigma_t)."""


class _Frozen(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def _object_name(value: str) -> str:
    from softsig_service.objects import OBJECT_NAMES

    if value not in OBJECT_NAMES:
        raise ValueError(f"unknown object {value!r}; built-in objects: {', '.join(OBJECT_NAMES)}")
    return value


def _strategy_name(value: str) -> str:
    from softsig_service.planning.strategies import STRATEGIES

    if value not in STRATEGIES:
        raise ValueError(f"unknown strategy {value!r}; strategies: {', '.join(STRATEGIES)}")
    return value


class _CellFields(_Frozen):
    object: str = Field(description="a built-in object's name")
    strategy: str = Field(description="the planner's strategy (S, C or R)")
    sigma_r: float = Field(0.0, ge=0.0, le=MAX_SIGMA_R, description="[rad] yaw noise of the trials")
    sigma_t: float = Field(0.0, ge=0.0, le=MAX_SIGMA_T, description="[m] x, y noise of the trials")

    @field_validator("object")
    @classmethod
    def _known_object(cls, value: str) -> str:
        return _object_name(value)

    @field_validator("strategy")
    @classmethod
    def _known_strategy(cls, value: str) -> str:
        return _strategy_name(value)

    @property
    def key(self) -> CellKey:
        """(object, strategy, sigma_r, sigma_t)."""
        return (self.object, self.strategy, float(self.sigma_r), float(self.sigma_t))


class RealCell(_CellFields):
    """Counts of one cell: ``successes`` of ``trials`` real trials."""

    trials: int = Field(ge=1, le=100_000)
    successes: int = Field(ge=0)

    @field_validator("successes")
    @classmethod
    def _at_most_trials(cls, value: int, info: ValidationInfo) -> int:
        trials = info.data.get("trials")
        if trials is not None and value > trials:
            raise ValueError(f"successes ({value}) exceed trials ({trials})")
        return value


class Offset(_Frozen):
    """The object's measured offset from its planned pose (table frame)."""

    d_yaw: float = Field(0.0, ge=-math.pi, le=math.pi, description="[rad]")
    dx: float = Field(0.0, ge=-0.2, le=0.2, description="[m]")
    dy: float = Field(0.0, ge=-0.2, le=0.2, description="[m]")


class RealTrial(_CellFields):
    """One real trial: its cell, its outcome and, if measured, the object's offset."""

    success: bool
    offset: Offset | None = None


class RealOutcomes(_Frozen):
    """A hand's real outcomes: ``cells`` (counts), ``trials`` (records) or both, never the same cell twice."""

    cells: tuple[RealCell, ...] = ()
    trials: tuple[RealTrial, ...] = ()
    note: str = Field("", max_length=2000, description="where the trials were run (robot, object set, date)")

    @model_validator(mode="after")
    def _not_empty_no_repeats(self) -> RealOutcomes:
        if not self.cells and not self.trials:
            raise ValueError("give at least one cell or one trial record")
        seen: set[CellKey] = set()
        for c in self.cells:
            if c.key in seen:
                raise ValueError(f"the cell {c.key} is given twice")
            seen.add(c.key)
        overlap = {t.key for t in self.trials} & seen
        if overlap:
            raise ValueError(f"cells given both as counts and as trial records: {sorted(overlap)}")
        return self

    def counts(self) -> dict[CellKey, tuple[int, int]]:
        """Successes and trials per cell, trial records counted into their cells (keys sorted)."""
        out: dict[CellKey, list[int]] = {c.key: [c.successes, c.trials] for c in self.cells}
        for t in self.trials:
            entry = out.setdefault(t.key, [0, 0])
            entry[0] += int(t.success)
            entry[1] += 1
        return {k: (v[0], v[1]) for k, v in sorted(out.items())}

    def trial_records(self, key: CellKey) -> list[RealTrial]:
        """The trial records of cell ``key``, in the order given."""
        return [t for t in self.trials if t.key == key]


class CellSelector(_Frozen):
    """Selects cells: each given field must match (an empty selector matches every cell)."""

    object: str | None = None
    strategy: str | None = None
    sigma_r: float | None = Field(None, ge=0.0)
    sigma_t: float | None = Field(None, ge=0.0)

    def matches(self, key: CellKey) -> bool:
        """Whether cell ``key`` has every field this selector gives (sigmas within 1e-9)."""
        obj, strategy, sr, st = key
        return (
            (self.object is None or self.object == obj)
            and (self.strategy is None or self.strategy == strategy)
            and (self.sigma_r is None or abs(self.sigma_r - sr) <= 1e-9)
            and (self.sigma_t is None or abs(self.sigma_t - st) <= 1e-9)
        )


def split_cells(keys: Sequence[CellKey], held_out: Sequence[CellSelector]) -> tuple[list[CellKey], list[CellKey]]:
    """(fitted, held out): a cell any selector matches is held out."""
    test = [k for k in keys if any(s.matches(k) for s in held_out)]
    return [k for k in keys if k not in test], test


def parse_model(model: type[BaseModel], data: Any, *, prefix: str = "") -> Any:
    """Validate ``data`` as ``model``; :class:`InvalidInput` naming the first bad field (``prefix`` before it)."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise invalid_input(exc, prefix) from None


def outcomes_from_json(data: Any) -> RealOutcomes:
    """:class:`RealOutcomes` from parsed JSON; :class:`InvalidInput` naming the first bad field."""
    result: RealOutcomes = parse_model(RealOutcomes, data)
    return result
