"""Strategy C's NLP over the arm's joints, timed side by side in one run: C on a box tilted about its long axis (the
joint NLP plans it) against C on the same box upright (the closed form), alternated, and against C where the closed
form's reach model gives up (the box at x = 0.9 m). Medians of the planner's ``timing.total``; ratios are the figures
to compare (target: within 2x of today's C plan).

Run: .venv/bin/python benchmarks/bench_joint_nlp.py [--n 30]
"""

from __future__ import annotations

import argparse
import math
import statistics


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30)
    args = parser.parse_args()

    from softsig_service.experiments.trial import default_planner
    from softsig_service.objects import builtin_object, object_from_json
    from softsig_service.planning.request import PlanRequest

    planner = default_planner()
    turn = {"x": math.sin(math.radians(10)), "y": 0.0, "z": 0.0, "w": math.cos(math.radians(10))}  # 20 deg about x
    pose = {"x": 0.5, "y": 0.0, "orientation": turn}
    tilted = {"kind": "box", "size": [0.16, 0.06, 0.05], "mass": 0.15, "pose": pose}
    cases = {
        "upright box (closed form)": builtin_object("box"),
        "box tilted 20 deg (joint NLP)": object_from_json(tilted),
        "box at x = 0.9 m (joint NLP after the closed form)": builtin_object("box", x=0.9),
    }
    times: dict[str, list[float]] = {k: [] for k in cases}
    status: dict[str, str] = {}
    for i in range(args.n + 2):
        for name, obj in cases.items():
            plan = planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="C"))  # type: ignore[arg-type]
            status[name] = f"{plan.success}, {plan.solver['status']}"
            if i >= 2:  # the first rounds compile the solvers
                times[name].append(plan.timing["total"])
    base = statistics.median(times["upright box (closed form)"])
    print(f"pisa_iit_softhand, strategy C, {args.n} plans each, medians of timing.total")
    print("| case | success, solver | median [ms] | x the upright C plan |")
    print("|---|---|---|---|")
    for name, ts in times.items():
        m = statistics.median(ts)
        print(f"| {name} | {status[name]} | {m * 1e3:.2f} | {m / base:.2f} |")


if __name__ == "__main__":
    main()
