"""The capture model (pure math): interpolation, periodicity, the expectation under pose noise, JSON, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.errors import InvalidInput
from softsig_service.signatures.capture import CaptureModel, agreement, theta_axis, uniform_axis, wrap_theta

TH = theta_axis(12)
U = uniform_axis(0.03, 0.01)


def random_model(seed: int) -> CaptureModel:
    rng = np.random.default_rng(seed)
    return CaptureModel(TH, U, U, rng.uniform(0.0, 1.0, (len(TH), len(U), len(U))))


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000))
def test_the_model_interpolates_its_grid_and_has_period_pi(seed: int) -> None:
    m = random_model(seed)
    T, Uu, V = np.meshgrid(TH, U, U, indexing="ij")
    assert np.allclose(m.probability(T, Uu, V), m.values, atol=1e-12), "exact at the nodes"
    assert np.allclose(m.probability(T + math.pi, Uu, V), m.values, atol=1e-9), "a half turn is the same pose"
    assert np.allclose(m.probability(T - 3 * math.pi, Uu, V), m.values, atol=1e-9)
    rng = np.random.default_rng(seed)
    t, u, v = rng.uniform(-4, 4, 50), rng.uniform(-0.03, 0.03, 50), rng.uniform(-0.03, 0.03, 50)
    p = m.probability(t, u, v)
    assert np.all(p >= 0) and np.all(p <= 1)
    assert np.all(p <= m.values.max() + 1e-12) and np.all(p >= m.values.min() - 1e-12), "a convex combination"


def test_beyond_the_grid_nothing_is_captured() -> None:
    m = CaptureModel(TH, U, U, np.ones((len(TH), len(U), len(U))))
    assert m.probability(0.3, 0.0, 0.0) == pytest.approx(1.0)
    assert m.probability(0.3, 0.035, 0.0) == pytest.approx(0.5), "halfway into the zero step beyond the edge"
    assert m.probability(0.3, 0.041, 0.0) == 0.0 and m.probability(0.3, 0.0, -0.2) == 0.0


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.floats(-3, 3), st.floats(-0.03, 0.03), st.floats(-0.03, 0.03))
def test_the_expectation_without_noise_is_the_probability(seed: int, t: float, u: float, v: float) -> None:
    m = random_model(seed)
    assert m.expected(t, u, v, 0.0, 0.0) == pytest.approx(float(m.probability(t, u, v)), abs=1e-12)


def test_the_expectation_matches_monte_carlo() -> None:
    m = random_model(3)
    rng = np.random.default_rng(0)
    sr, s_t = 0.2, 0.01
    n = 200_000
    mc = m.probability(0.1 + sr * rng.standard_normal(n), s_t * rng.standard_normal(n), s_t * rng.standard_normal(n))
    assert m.expected(0.1, 0.0, 0.0, sr, s_t) == pytest.approx(float(mc.mean()), abs=5e-3)


def test_a_uniform_model_keeps_its_value_under_yaw_noise() -> None:
    m = CaptureModel(TH, U, U, np.full((len(TH), len(U), len(U)), 0.7))
    assert m.expected(0.4, 0.0, 0.0, 1.0, 0.0) == pytest.approx(0.7, abs=1e-12)


def test_json_round_trip_and_agreement() -> None:
    m = random_model(5)
    back = CaptureModel.from_json_dict(m.to_json_dict())
    assert np.array_equal(back.values, m.values) and np.array_equal(back.theta, m.theta)
    samples = [(float(t), 0.0, 0.0, bool(m.probability(t, 0.0, 0.0) >= 0.5)) for t in TH]
    assert agreement(m, samples) == 1.0
    flipped = [(t, u, v, not c) for t, u, v, c in samples]
    assert agreement(m, flipped) == 0.0
    assert math.isnan(agreement(m, []))


def test_wrap_theta() -> None:
    assert wrap_theta(math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_theta(-math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_theta(3.0) == pytest.approx(3.0 - math.pi)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"values": np.zeros((12, 7, 6))}, "values"),
        ({"values": np.full((12, 7, 7), 1.5)}, "values"),
        ({"values": np.full((12, 7, 7), np.nan)}, "values"),
        ({"theta": np.linspace(0, 1, 12)}, "theta"),
        ({"u": U[::-1].copy()}, "u"),
    ],
)
def test_bad_models_name_the_field(kwargs: dict[str, np.ndarray], field: str) -> None:
    args = {"theta": TH, "u": U, "v": U, "values": np.zeros((12, 7, 7)), **kwargs}
    with pytest.raises(InvalidInput) as info:
        CaptureModel(**args)
    assert info.value.field == field
    with pytest.raises(InvalidInput) as info:
        CaptureModel.from_json_dict({"theta": [0.0]})
    assert info.value.field == "capture"
