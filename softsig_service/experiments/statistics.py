"""Statistics of a campaign: success counts per cell, Wilson 95 % intervals and Fisher's exact tests of S vs C
(``scipy.stats``), per cell, pooled per condition and overall.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from softsig_service.experiments.campaign_spec import PAPER_TABLE1, PAPER_TRIALS, TABLE1_CONDITIONS, CampaignSpec


def wilson_interval(successes: int, n: int) -> tuple[float, float]:
    """Wilson score 95 % interval of a success rate (``scipy.stats.binomtest(...).proportion_ci``)."""
    from scipy.stats import binomtest

    if n == 0:
        return (0.0, 1.0)
    ci = binomtest(successes, n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)


def fisher_p(s_succ: int, s_n: int, c_succ: int, c_n: int) -> dict[str, float]:
    """Fisher's exact test of S vs C on the 2x2 table [[S succ, S fail], [C succ, C fail]]:
    ``two_sided`` and ``c_greater`` (one-sided, alternative: C's success rate is higher)."""
    from scipy.stats import fisher_exact

    table = [[s_succ, s_n - s_succ], [c_succ, c_n - c_succ]]
    two = fisher_exact(table, alternative="two-sided").pvalue
    less = fisher_exact(table, alternative="less").pvalue  # odds(S) < odds(C)
    return {"two_sided": float(two), "c_greater": float(less)}


def r_versus_best(pairs: Mapping[str, tuple[int, int]]) -> dict[str, Any]:
    """Fisher's exact test of R against the better of S and C (by success rate; C on a tie): ``versus`` (which),
    ``two_sided`` and ``r_greater`` (one-sided, alternative: R's success rate is higher)."""
    rates = {s: (k / n if n else -1.0) for s, (k, n) in pairs.items() if s in ("S", "C")}
    best = max(rates, key=lambda s: (rates[s], s == "C"))
    p = fisher_p(*pairs[best], *pairs["R"])
    return {"versus": best, "two_sided": p["two_sided"], "r_greater": p["c_greater"]}


def _counts(records: Iterable[Mapping[str, Any]]) -> dict[tuple[int, str, str], tuple[int, int]]:
    out: dict[tuple[int, str, str], list[int]] = {}
    for r in records:
        k = (int(r["condition"]), str(r["object"]), str(r["strategy"]))
        c = out.setdefault(k, [0, 0])
        c[0] += bool(r["success"])
        c[1] += 1
    return {k: (v[0], v[1]) for k, v in out.items()}


def summarize(spec: CampaignSpec, records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Counts, Wilson intervals and Fisher p-values per cell, pooled per condition and overall, the failure
    reasons per cell, and the paper's counts where the grid matches Table I."""
    counts = _counts(records)
    cells: list[dict[str, Any]] = []

    def stats(pairs: dict[str, tuple[int, int]]) -> dict[str, Any]:
        d: dict[str, Any] = {}
        for s, (k, n) in pairs.items():
            d[s] = {"successes": k, "trials": n, "rate": k / n if n else None, "wilson95": wilson_interval(k, n)}
        if "S" in pairs and "C" in pairs:
            d["fisher"] = fisher_p(*pairs["S"], *pairs["C"])
        if "R" in pairs and ("S" in pairs or "C" in pairs):
            d["fisher_r"] = r_versus_best(pairs)
        return d

    paper = _paper_counts(spec)
    for i, cond in enumerate(spec.conditions):
        for obj in spec.objects:
            pairs = {s: counts.get((i, obj, s), (0, 0)) for s in spec.strategies}
            reasons = {
                s: dict(
                    Counter(
                        str(r["reason"])
                        for r in records
                        if int(r["condition"]) == i and r["object"] == obj and r["strategy"] == s and not r["success"]
                    )
                )
                for s in spec.strategies
            }
            cell = {
                "condition": i,
                "sigma_r": cond[0],
                "sigma_t": cond[1],
                "object": obj,
                **stats(pairs),
                "reasons": reasons,
            }
            if paper is not None and obj in PAPER_TABLE1:
                ps, pc = PAPER_TABLE1[obj][i]
                cell["paper"] = {
                    "S": ps,
                    "C": pc,
                    "trials": PAPER_TRIALS,
                    "fisher": fisher_p(ps, PAPER_TRIALS, pc, PAPER_TRIALS),
                }
            cells.append(cell)
    pooled: list[dict[str, Any]] = []
    for i, cond in enumerate(spec.conditions):
        pairs = {s: _sum(counts.get((i, o, s), (0, 0)) for o in spec.objects) for s in spec.strategies}
        pooled.append({"condition": i, "sigma_r": cond[0], "sigma_t": cond[1], **stats(pairs)})
    overall = stats({s: _sum(v for k, v in counts.items() if k[2] == s) for s in spec.strategies})
    return {"cells": cells, "pooled_per_condition": pooled, "pooled": overall, "paper_available": paper is not None}


def _sum(pairs: Iterable[tuple[int, int]]) -> tuple[int, int]:
    k = n = 0
    for a, b in pairs:
        k, n = k + a, n + b
    return k, n


def _paper_counts(spec: CampaignSpec) -> dict[str, tuple[tuple[int, int], ...]] | None:
    """The paper's counts if the conditions are Table I's."""
    if tuple(spec.conditions) != TABLE1_CONDITIONS:
        return None
    return PAPER_TABLE1
