"""Top-grasp plan latency in-process: p50/p95 [ms] for strategies S and C on the three built-in objects.

Objects are placed at random reachable table poses (x in [0.35, 0.6] m, y in [-0.25, 0.25] m, any yaw) from a
fixed seed; models are built before timing (as the service does at start-up). The split columns show where
the time goes: the strategy (C: the CasADi NLP, both yaw branches), UR5 IK (grasp for both branches, pre-grasp
and approach waypoints of the chosen one) and collision work (descent along the approach + coal checks).

Run: .venv/bin/python benchmarks/bench_planner.py [--n 200] [--hand pisa_iit_softhand]
IK success over random reachable poses: .venv/bin/python benchmarks/bench_ur5.py
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()

from softsig_service.objects import BUILTIN_NAMES, builtin_object  # noqa: E402
from softsig_service.planning.planner import Planner, PlanRequest, planning_model  # noqa: E402


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(q * (len(s) - 1)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=200, help="plans per (strategy, object)")
    parser.add_argument("--hand", default="pisa_iit_softhand")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    planner = Planner()
    planning_model(args.hand)
    rng = np.random.default_rng(args.seed)
    print(f"hand {args.hand}, {args.n} plans per cell")
    print(f"{'strategy':8s} {'object':9s} {'ok':>5s} {'p50 [ms]':>9s} {'p95 [ms]':>9s} "
          f"{'strategy':>9s} {'IK':>6s} {'coll.':>6s}  (medians [ms])")  # fmt: skip
    for strategy in ("S", "C"):
        for name in BUILTIN_NAMES:
            total, strat, ik, col, ok = [], [], [], [], 0
            for _ in range(args.n):
                obj = builtin_object(name, x=rng.uniform(0.35, 0.6), y=rng.uniform(-0.25, 0.25),
                                     yaw=rng.uniform(-np.pi, np.pi))  # fmt: skip
                req = PlanRequest(hand=args.hand, obj=obj, strategy=strategy)  # type: ignore[arg-type]
                t0 = time.perf_counter()
                plan = planner.plan(req)
                total.append((time.perf_counter() - t0) * 1e3)
                strat.append(plan.timing["strategy"] * 1e3)
                ik.append(plan.timing["ik"] * 1e3)
                col.append(plan.timing["collision"] * 1e3)
                ok += plan.success
            med = [statistics.median(v) for v in (strat, ik, col)]
            print(f"{strategy:8s} {name:9s} {ok:5d} {pct(total, 0.5):9.2f} {pct(total, 0.95):9.2f} "
                  f"{med[0]:9.2f} {med[1]:6.2f} {med[2]:6.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
