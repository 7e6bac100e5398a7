"""Ranked grasps timed side by side in one run (ratios, not seconds, are the figures to compare on a shared
machine): a plan with ``candidates = k`` against the plan with one candidate, same hand, objects and random
reachable object poses, alternated request by request (target: k = 5 within 3x of one). The time of a plan is the
planner's own ``timing.total`` (thread CPU is not separated: the figures include the machine's load).

Run: .venv/bin/python benchmarks/bench_ranking.py [--n 60] [--k 5] [--hand pisa_iit_softhand]
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=60, help="object poses (each planned with 1 and k candidates)")
    parser.add_argument("--k", type=int, default=5)
    parser.add_argument("--hand", default="pisa_iit_softhand")
    args = parser.parse_args()

    from softsig_service.experiments.trial import default_planner
    from softsig_service.objects import builtin_object
    from softsig_service.planning.request import PlanRequest

    planner = default_planner()
    rng = np.random.default_rng(0)
    rows = []
    for strategy in ("S", "C"):
        one, many, returned = [], [], []
        for i in range(args.n):
            name = ("box", "apple", "cylinder")[i % 3]
            obj = builtin_object(name, x=float(rng.uniform(0.4, 0.6)), y=float(rng.uniform(-0.15, 0.15)),
                                 yaw=float(rng.uniform(-np.pi, np.pi)))  # fmt: skip
            for k, sink in ((1, one), (args.k, many)):
                plan = planner.plan(PlanRequest(hand=args.hand, obj=obj, strategy=strategy, candidates=k))  # type: ignore[arg-type]
                if i >= 3:  # the first poses warm the caches
                    sink.append(plan.timing["total"])
                if k > 1:
                    returned.append(len(plan.grasps))
        a, b = statistics.median(one), statistics.median(many)
        rows.append((strategy, a * 1e3, b * 1e3, b / a, statistics.mean(returned)))
    print(f"hand {args.hand}, {args.n} poses per strategy, medians of the planner's timing.total")
    print(f"| strategy | 1 candidate [ms] | {args.k} candidates [ms] | ratio | grasps returned (mean) |")
    print("|---|---|---|---|---|")
    for s, a, b, r, m in rows:
        print(f"| {s} | {a:.2f} | {b:.2f} | {r:.2f} | {m:.2f} |")


if __name__ == "__main__":
    main()
