"""How far a long run has got, how fast it goes and how long it has left: the one text every progress report of the
experiments shows (the command line's bar, a job's ``message`` in the API).

:class:`Progress` counts the items done in this run (work done before, as a resumed campaign's recorded trials, is
neither counted in the rate nor left to do), their mean rate [items/s] since the run started, and the time left at
that rate [s].
"""

from __future__ import annotations

import time
from collections.abc import Callable


class Progress:
    """Progress of a run of ``total`` items of which ``start`` were done before it began; ``clock`` [s] is any
    monotonic clock (default :func:`time.monotonic`)."""

    def __init__(self, total: int, start: int = 0, clock: Callable[[], float] = time.monotonic) -> None:
        self.total = total
        self.start = start
        self.done = start
        self._clock = clock
        self._t0 = clock()

    def update(self, done: int) -> None:
        """Record that ``done`` items (counting those done before the run) are finished."""
        self.done = done

    @property
    def fraction(self) -> float:
        """Share of all items done, in [0, 1] (1 for an empty run)."""
        return min(1.0, self.done / self.total) if self.total else 1.0

    @property
    def rate(self) -> float | None:
        """[items/s] items of this run per second since it began (None before the first, or with no time elapsed)."""
        elapsed = self._clock() - self._t0
        ran = self.done - self.start
        return ran / elapsed if ran > 0 and elapsed > 0.0 else None

    @property
    def remaining(self) -> float | None:
        """[s] time left at :attr:`rate` (0 when all are done; None when the rate is not known yet)."""
        left = max(0, self.total - self.done)
        if left == 0:
            return 0.0
        rate = self.rate
        return left / rate if rate else None

    def message(self, noun: str = "trials") -> str:
        """``"120 of 3600 trials, 5.2 trials/s, 11 min 8 s left"`` (rate and time left once known)."""
        text = f"{self.done} of {self.total} {noun}"
        rate, left = self.rate, self.remaining
        if rate is not None:
            text += f", {rate:.3g} {noun}/s"
        if left is not None and self.done < self.total:
            text += f", {duration_text(left)} left"
        return text


def duration_text(seconds: float) -> str:
    """``"42 s"``, ``"11 min 8 s"``, ``"2 h 5 min"``: a duration [s] as a person reads it."""
    s = max(0, round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60} s"
    return f"{s // 3600} h {(s % 3600) // 60} min"
