"""Plain JSON of computed results: NumPy values made plain, non-finite floats null, 3-D vectors as {x, y, z}."""

from __future__ import annotations

import json
import math
from collections import OrderedDict

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from softsig_service.services.serialize import to_jsonable, vectors_as_objects

_leaves = st.one_of(
    st.none(), st.booleans(), st.integers(-(10**6), 10**6), st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=5),
)  # fmt: skip
_json = st.recursive(
    _leaves,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=4), inner, max_size=4),
    max_leaves=20,
)


def test_numpy_values_tuples_and_non_finite_floats() -> None:
    value = {
        "a": np.float64(1.5), "b": np.int64(3), "c": np.array([[1.0, float("nan")], [2.0, 3.0]]),
        "d": (1, np.bool_(True)), "e": float("inf"), 7: OrderedDict(x=np.float32(0.5)), "f": [None, "s"],
    }  # fmt: skip
    out = to_jsonable(value)
    assert out == {"a": 1.5, "b": 3, "c": [[1.0, None], [2.0, 3.0]], "d": [1, True], "e": None,
                   "7": {"x": 0.5}, "f": [None, "s"]}  # fmt: skip
    json.dumps(out, allow_nan=False)  # valid JSON


@given(_json)
def test_plain_json_comes_back_equal_with_non_finite_floats_null(value: object) -> None:
    def expected(v: object) -> object:
        if isinstance(v, float) and not math.isfinite(v):
            return None
        if isinstance(v, list):
            return [expected(x) for x in v]
        if isinstance(v, dict):
            return {k: expected(x) for k, x in v.items()}
        return v

    out = to_jsonable(value)
    assert out == expected(value)
    json.dumps(out, allow_nan=False)
    assert to_jsonable(out) == out  # idempotent


def test_vectors_under_vector_keys_become_objects_and_other_lists_stay() -> None:
    plan = {
        "approach": {"direction": [0.0, 0.0, -1.0], "desired_distance": 0.1},
        "closure": {"axis": [1, 0, 0], "axes": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], "values": [1.0, 2.0, 3.0]},
        "joint_positions": [0.1, 0.2, 0.3],
        "center": [1.0, 2.0],  # not a triple
        "items": [{"position": [1.0, 2.0, 3.0]}],
    }
    assert vectors_as_objects(plan) == {
        "approach": {"direction": {"x": 0.0, "y": 0.0, "z": -1.0}, "desired_distance": 0.1},
        "closure": {"axis": {"x": 1, "y": 0, "z": 0},
                    "axes": [{"x": 1.0, "y": 0.0, "z": 0.0}, {"x": 0.0, "y": 1.0, "z": 0.0}],
                    "values": [1.0, 2.0, 3.0]},
        "joint_positions": [0.1, 0.2, 0.3],
        "center": [1.0, 2.0],
        "items": [{"position": {"x": 1.0, "y": 2.0, "z": 3.0}}],
    }  # fmt: skip
    assert vectors_as_objects(OrderedDict(normal=[0.0, 0.0, 1.0])) == {"normal": {"x": 0.0, "y": 0.0, "z": 1.0}}


_keys = st.sampled_from(["axis", "axes", "origin", "x", "y", "z", "center", "directions", "q", "name"]) | st.text(
    max_size=3
)
_vectors = st.lists(st.floats(allow_nan=True, allow_infinity=True) | st.integers(-5, 5), min_size=3, max_size=3)
_numpy = _vectors.map(lambda v: np.array(v, dtype=np.float64)) | st.floats().map(np.float64)
_api = st.recursive(
    _leaves | _vectors | _numpy,
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.lists(inner, max_size=3).map(tuple)
        | st.dictionaries(_keys | st.integers(0, 3), inner, max_size=5)
    ),
    max_leaves=25,
)


@given(_api)
def test_the_one_pass_form_is_the_two_passes(value: object) -> None:
    """The API's one-pass conversion gives exactly what the two passes give, numpy values, tuples, frames and
    non-string keys included."""
    from softsig_service.services.serialize import api_json

    assert json.dumps(api_json(value)) == json.dumps(vectors_as_objects(to_jsonable(value)))
