"""The progress text of long runs: rate and time left from this run's items only, on a clock the test drives."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from softsig_service.experiments.progress import Progress, duration_text


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_rate_and_time_left_count_this_run_only() -> None:
    clock = Clock()
    p = Progress(3600, start=600, clock=clock)  # a resumed campaign: 600 recorded before
    assert p.rate is None and p.remaining is None and p.message() == "600 of 3600 trials"
    clock.t += 60.0
    p.update(900)  # 300 trials in 60 s
    assert p.rate == 5.0 and p.remaining == 540.0
    assert p.message() == "900 of 3600 trials, 5 trials/s, 9 min 0 s left"
    assert p.fraction == 0.25
    p.update(3600)
    assert p.remaining == 0.0 and p.fraction == 1.0 and "left" not in p.message()


@given(st.floats(0, 10 * 3600, allow_nan=False))
def test_durations_read_back_to_within_a_minute(seconds: float) -> None:
    text = duration_text(seconds).split()
    units = {"h": 3600, "min": 60, "s": 1}
    total = sum(int(v) * units[u] for v, u in zip(text[::2], text[1::2], strict=True))
    assert abs(total - seconds) <= (60 if seconds >= 3600 else 0.5)
