"""How good the ranked grasps are: success per rank, and how well ``grasp_quality`` predicts success.

For each hand, object (the Table I box, apple and cylinder at the nominal pose) and strategy (S, C), the planner
returns ``k`` ranked grasps (:mod:`softsig_service.planning.ranking`) with the quality of the stated noise
(``sigma_r``, ``sigma_t``: the Table I condition the grasps are validated under); every grasp is then validated
``trials`` times under that noise (:func:`~softsig_service.experiments.trial.run_trial` with the grasp as the plan,
trial ``j`` of every grasp of a cell drawing the same perturbation). The quality of each grasp is recorded from both
models: the one the service used (``capture`` where the hand ships a capture model of the object, else
``geometric``) and the geometric one.

Output: ``ranking.json`` (every trial), ``ranking.md`` (success per rank with Wilson intervals, Fisher's exact test
of rank 1 against rank k, pooled; the calibration table: grasps binned by predicted quality, mean prediction vs the
observed rate, and the Brier score of each model) and ``ranking.png`` (the reliability diagram).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from softsig_service.experiments.campaign_spec import STRATEGY_NAMES, TABLE1_CONDITIONS, TABLE1_OBJECTS, trial_seed

BINS = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)
"""Edges of the predicted-quality bins of the calibration table and diagram."""


@dataclass(frozen=True)
class _Task:
    hand: str
    object: str
    strategy: str
    rank: int
    trial: int
    seed: int
    condition: int
    k: int


def ranked_plans(hand: str, obj_name: str, strategy: str, k: int, sigma_r: float, sigma_t: float) -> Any:
    """The plan with ``k`` ranked grasps the service would answer (the hand's shipped capture model of the object
    for the quality where there is one) for the built-in object at its nominal pose."""
    from softsig_service.experiments.capture import shipped_capture_for
    from softsig_service.experiments.trial import default_planner
    from softsig_service.hands.model import resolve_hand_path
    from softsig_service.objects import builtin_object
    from softsig_service.planning.request import PlanRequest
    from softsig_service.signatures.capture import CaptureModel

    obj = builtin_object(obj_name)
    path = shipped_capture_for(resolve_hand_path(hand).parent, obj)
    capture = None if path is None else CaptureModel.from_json_dict(json.loads(path.read_text(encoding="utf-8")))
    return default_planner().plan(PlanRequest(hand=hand, obj=obj, strategy=strategy, candidates=k,  # type: ignore[arg-type]
                                              sigma_r=sigma_r, sigma_t=sigma_t, capture=capture))  # fmt: skip


_PLANS: dict[tuple[str, str, str, int, int], Any] = {}


def _run(task: _Task) -> dict[str, Any] | None:
    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()
    from softsig_service.experiments.trial import run_trial
    from softsig_service.objects import builtin_object
    from softsig_service.planning.hand_model import planning_model
    from softsig_service.planning.ranking import geometric_quality

    sigma_r, sigma_t = TABLE1_CONDITIONS[task.condition]
    key = (task.hand, task.object, task.strategy, task.k, task.condition)
    if key not in _PLANS:
        _PLANS[key] = ranked_plans(task.hand, task.object, task.strategy, task.k, sigma_r, sigma_t)
    plan = _PLANS[key]
    if task.rank > len(plan.grasps):
        return None
    g = plan.grasps[task.rank - 1]
    single = dataclasses.replace(
        plan, grasp_pose=g["grasp_pose"], pre_grasp_pose=g["pre_grasp_pose"], joint_positions=g["joint_positions"],
        pre_grasp_joint_positions=g["pre_grasp_joint_positions"], grasp_frame_pose=g["grasp_frame_pose"], grasps=[g],
    )  # fmt: skip
    obj = builtin_object(task.object)
    result = run_trial(task.hand, obj, task.strategy, seed=task.seed, sigma_r=sigma_r, sigma_t=sigma_t,  # type: ignore[arg-type]
                       plan=single)  # fmt: skip
    model = planning_model(task.hand, "ellipsoid")
    geometric = geometric_quality(
        g["grasp_frame_pose"], model.signature.axis, model.placement_point("R", "open_centre"), obj
    )
    return {"hand": task.hand, "object": task.object, "strategy": task.strategy, "rank": task.rank,
            "trial": task.trial, "seed": task.seed, "quality": g["grasp_quality"], "quality_model": g["quality_model"],
            "geometric_quality": geometric, "label": g["label"], "success": result.success,
            "reason": result.reason}  # fmt: skip


def run_ranking(
    out: Path, *, hands: tuple[str, ...] = ("pisa_iit_softhand", "rbo_hand2"), k: int = 6, trials: int = 30,
    condition: int = 1, seed: int = 0, workers: int = 1, progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Run the campaign (module docstring) into ``out``; the summary (also in ``ranking.json``)."""
    tasks = [
        _Task(hand, obj, strat, rank, j, trial_seed(seed, (h, o, s, condition), j), condition, k)
        for h, hand in enumerate(hands)
        for o, obj in enumerate(TABLE1_OBJECTS)
        for s, strat in enumerate(STRATEGY_NAMES)
        for rank in range(1, k + 1)
        for j in range(trials)
    ]
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    records: list[dict[str, Any]] = []
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) if workers > 1 else None
    results: Iterator[dict[str, Any] | None] = (
        pool.map(_run, tasks, chunksize=trials) if pool is not None else map(_run, tasks)
    )
    for done, r in enumerate(results, start=1):
        if r is not None:
            records.append(r)
        if progress:
            progress(done, len(tasks))
    if pool is not None:
        pool.shutdown()
    summary = summarize(records, k)
    summary.update(hands=list(hands), k=k, trials=trials, condition=condition, seed=seed,
                   sigma=TABLE1_CONDITIONS[condition], wall_time=time.perf_counter() - t0)  # fmt: skip
    (out / "ranking.json").write_text(json.dumps({**summary, "records": records}, indent=1) + "\n", encoding="utf-8")
    (out / "ranking.md").write_text(report(summary), encoding="utf-8")
    draw_reliability(summary, out / "ranking.png")
    return summary


def _calibration(pred: np.ndarray, hit: np.ndarray) -> dict[str, Any]:
    rows = []
    for lo, hi in itertools.pairwise(BINS):
        m = (pred >= lo) & ((pred < hi) if hi < 1.0 else (pred <= hi))
        if m.any():
            rows.append({"bin": [lo, hi], "n": int(m.sum()), "predicted": float(pred[m].mean()),
                         "observed": float(hit[m].mean())})  # fmt: skip
    brier = float(np.mean((pred - hit) ** 2)) if len(pred) else float("nan")
    return {"bins": rows, "brier": brier, "n": len(pred)}


def summarize(records: list[dict[str, Any]], k: int) -> dict[str, Any]:
    """Success per rank (pooled and per hand), rank 1 vs rank k, and the calibration of both quality models."""
    from softsig_service.experiments.statistics import fisher_p, wilson_interval

    def per_rank(rs: list[dict[str, Any]]) -> list[dict[str, Any]]:
        rows = []
        for rank in range(1, k + 1):
            mine = [r["success"] for r in rs if r["rank"] == rank]
            rows.append({"rank": rank, "successes": int(sum(mine)), "trials": len(mine),
                         "wilson": wilson_interval(int(sum(mine)), len(mine))})  # fmt: skip
        return rows

    pooled = per_rank(records)
    first, last = pooled[0], next((r for r in reversed(pooled) if r["trials"]), pooled[-1])
    # fisher_p's one-sided alternative is "the second has the higher rate": rank k first, rank 1 second
    test = fisher_p(last["successes"], last["trials"], first["successes"], first["trials"])
    hands = sorted({r["hand"] for r in records})
    hit = np.array([float(r["success"]) for r in records])
    served = np.array([r["quality"] for r in records])
    geometric = np.array([r["geometric_quality"] for r in records])
    capture_only = np.array([r["quality_model"] == "capture" for r in records], dtype=bool)
    return {
        "per_rank": pooled,
        "per_hand": {h: per_rank([r for r in records if r["hand"] == h]) for h in hands},
        "rank1_vs_rankk": {"rank_k": last["rank"], "two_sided": test["two_sided"], "rank1_greater": test["c_greater"]},
        "calibration": {
            "capture": _calibration(served[capture_only], hit[capture_only]),
            "geometric": _calibration(geometric, hit),
        },
    }


def report(summary: dict[str, Any]) -> str:
    """The Markdown tables of a summary of :func:`run_ranking`."""
    sr, st = summary["sigma"]
    lines = [
        f"Hands {', '.join(summary['hands'])}; objects {', '.join(TABLE1_OBJECTS)}; strategies S and C; "
        f"k = {summary['k']} ranked grasps each, every one validated {summary['trials']} times at sigma_r = {sr:g} "
        f"rad, sigma_t = {st:g} m (seed {summary['seed']}).",
        "",
        "| rank | pooled | " + " | ".join(summary["per_hand"]) + " |",
        "|---|---|" + "---|" * len(summary["per_hand"]),
    ]
    for i, row in enumerate(summary["per_rank"]):
        lo, hi = row["wilson"]
        cells = [f"{row['successes']}/{row['trials']} ({lo:.2f}-{hi:.2f})"]
        for rows in summary["per_hand"].values():
            cells.append(f"{rows[i]['successes']}/{rows[i]['trials']}")
        lines.append(f"| {row['rank']} | " + " | ".join(cells) + " |")
    t = summary["rank1_vs_rankk"]
    lines += ["", f"Fisher's exact test, rank 1 against rank {t['rank_k']} (pooled): one-sided p (rank 1 better) = "
              f"{t['rank1_greater']:.3g}, two-sided p = {t['two_sided']:.3g}.", ""]  # fmt: skip
    for name, cal in summary["calibration"].items():
        lines += [
            f"Calibration of the {name} model ({cal['n']} trials; Brier score {cal['brier']:.3f}):",
            "",
            "| predicted quality | trials | mean predicted | observed success |",
            "|---|---|---|---|",
        ]
        for b in cal["bins"]:
            lo, hi = b["bin"]
            lines.append(f"| {lo:.1f}-{hi:.1f} | {b['n']} | {b['predicted']:.3f} | {b['observed']:.3f} |")
        lines.append("")
    return "\n".join(lines)


def draw_reliability(summary: dict[str, Any], path: Path) -> None:
    """The reliability diagram (observed success against mean predicted quality per bin, each model) and the
    success rate per rank, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 5), facecolor="white")
    ax.plot([0, 1], [0, 1], ls="--", color="grey", label="perfectly calibrated")
    for (name, cal), colour in zip(summary["calibration"].items(), ("tab:blue", "tab:orange"), strict=False):
        xs = [b["predicted"] for b in cal["bins"]]
        ys = [b["observed"] for b in cal["bins"]]
        ax.plot(xs, ys, marker="o", color=colour, label=f"{name} (Brier {cal['brier']:.3f}, {cal['n']} trials)")
        for x, y, b in zip(xs, ys, cal["bins"], strict=True):
            ax.annotate(str(b["n"]), (x, y), textcoords="offset points", xytext=(4, -10), fontsize=8, color=colour)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("predicted grasp_quality (bin mean)")
    ax.set_ylabel("observed success rate")
    ax.set_title("Reliability of grasp_quality (numbers: trials per bin)")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    ranks = [r["rank"] for r in summary["per_rank"]]
    for hand, rows in summary["per_hand"].items():
        bx.plot(ranks, [r["successes"] / max(r["trials"], 1) for r in rows], marker="o", label=hand)
    pooled = summary["per_rank"]
    bx.errorbar(ranks, [r["successes"] / max(r["trials"], 1) for r in pooled],
                yerr=np.array([[r["successes"] / max(r["trials"], 1) - r["wilson"][0] for r in pooled],
                               [r["wilson"][1] - r["successes"] / max(r["trials"], 1) for r in pooled]]),
                color="black", marker="s", capsize=3, label="pooled (Wilson 95%)")  # fmt: skip
    bx.set_xlabel("rank")
    bx.set_ylabel("success rate")
    bx.set_ylim(0, 1)
    bx.set_xticks(ranks)
    bx.set_title("Success per rank")
    bx.legend(fontsize=8)
    bx.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
