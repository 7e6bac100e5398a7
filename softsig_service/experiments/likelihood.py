"""The likelihood of real outcomes under simulated success rates, with the simulations' own noise.

A cell's success probability is not known from the simulation, only estimated: ``s`` successes in ``m`` simulated
trials. Under the Jeffreys prior its posterior is ``Beta(s + 1/2, m - s + 1/2)``, and the probability of ``k``
real successes in ``n`` trials, with that uncertainty integrated out, is the beta-binomial

    P(k | n, s, m) = C(n, k) B(k + s + 1/2, n - k + m - s + 1/2) / B(s + 1/2, m - s + 1/2).

So a cell simulated with few trials (a deterministic nominal cell is one simulation) predicts with the confidence
it has, and a model is never ranked by Monte Carlo luck alone. The log of it summed over cells is the objective of
a calibration and the figure of merit on held-out cells.
"""

from __future__ import annotations

import math

from scipy.special import betaln, gammaln
from scipy.stats import beta as beta_dist

JEFFREYS = 0.5
"""The Jeffreys prior's Beta(1/2, 1/2) pseudo-counts."""


def log_binomial_coefficient(n: int, k: int) -> float:
    """``log C(n, k)``."""
    return float(gammaln(n + 1) - gammaln(k + 1) - gammaln(n - k + 1))


def beta_binomial_logpmf(k: int, n: int, s: int, m: int) -> float:
    """``log P(k | n, s, m)`` (module docstring): ``k`` of ``n`` real successes given ``s`` of ``m`` simulated."""
    if not (0 <= k <= n and 0 <= s <= m):
        raise ValueError(f"need 0 <= k <= n and 0 <= s <= m, got k={k}, n={n}, s={s}, m={m}")
    a, b = s + JEFFREYS, m - s + JEFFREYS
    return log_binomial_coefficient(n, k) + float(betaln(k + a, n - k + b) - betaln(a, b))


def binomial_logpmf(k: int, n: int, p: float) -> float:
    """``log P(k | n, p)`` of a binomial (a rate known exactly: the constant-rate baseline)."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"p must lie in (0, 1), got {p}")
    return log_binomial_coefficient(n, k) + k * math.log(p) + (n - k) * math.log1p(-p)


def jeffreys_interval(s: int, m: int, level: float = 0.95) -> tuple[float, float]:
    """The equal-tailed ``level`` interval of ``Beta(s + 1/2, m - s + 1/2)``: the simulated rate's uncertainty."""
    a, b = s + JEFFREYS, m - s + JEFFREYS
    tail = (1.0 - level) / 2.0
    return float(beta_dist.ppf(tail, a, b)), float(beta_dist.ppf(1.0 - tail, a, b))


def predicted_rate(s: int, m: int) -> float:
    """The posterior mean ``(s + 1/2) / (m + 1)``: the probability the beta-binomial gives one real success."""
    return (s + JEFFREYS) / (m + 2 * JEFFREYS)
