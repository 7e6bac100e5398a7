"""The registry's JSON columns are written by ``json_text`` (pydantic-core's serialiser): the same values read back
as ``json.dumps`` would give, NaN and infinities included."""

from __future__ import annotations

import json
import math
from typing import Any

from hypothesis import given
from hypothesis import strategies as st

from softsig_service.registry.db import json_text

SCALARS = st.none() | st.booleans() | st.integers() | st.floats() | st.text()
VALUES = st.recursive(
    SCALARS, lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(), inner, max_size=5), max_leaves=30
)


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1.0, a) == math.copysign(1.0, b))
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


@given(VALUES)
def test_json_text_reads_back_as_json_dumps(value: Any) -> None:
    assert _same(json.loads(json_text(value)), json.loads(json.dumps(value)))


def test_json_text_keeps_non_finite_numbers_and_unicode() -> None:
    text = json_text({"f": [float("nan"), float("inf"), -float("inf"), -0.0, 0.1 + 0.2], "s": "ü€"})
    back = json.loads(text)
    assert math.isnan(back["f"][0]) and back["f"][1:3] == [math.inf, -math.inf]
    assert math.copysign(1.0, back["f"][3]) == -1.0 and back["f"][4] == 0.1 + 0.2
    assert back["s"] == "ü€"
