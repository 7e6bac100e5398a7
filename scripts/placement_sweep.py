"""Diagnostic: nominal Table I grasps (S and C, box, apple, cylinder) with the hand point over the object's centre
moved to each of a grid of hand-frame points, to map how wide the basin of a carried object is.

Usage: python scripts/placement_sweep.py [--hand H] -- X,Y [X,Y ...]   (hand-frame x, y in mm)

Every point replaces the x, y of the placement point (docs/design.md §6) for both strategies; the planner then
plans as usual (descent, IK, collision checks) and the trial is rolled out and judged as in a campaign (seed 1,
no pose noise). Prints one line per point: ``strategy:object=OK|reason`` for the six nominal cells.
"""

from __future__ import annotations

import argparse

import numpy as np

from softsig_service.experiments.trial import default_planner, run_trial
from softsig_service.objects import builtin_object
from softsig_service.planning import hand_model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hand", default="pisa_iit_softhand")
    ap.add_argument("points", nargs="+", help="hand-frame x,y [mm]")
    args = ap.parse_args()
    planner = default_planner()
    point: list[float] = []
    original = hand_model.HandPlanningModel.placement_point

    def moved(self: hand_model.HandPlanningModel, strategy: str, placement: hand_model.Placement) -> np.ndarray:
        c = np.array(original(self, strategy, placement), dtype=np.float64)
        c[:2] = np.asarray(point) / 1000.0
        return c

    hand_model.HandPlanningModel.placement_point = moved  # type: ignore[method-assign]
    for text in args.points:
        point[:] = [float(v) for v in text.split(",")]
        cells = []
        for strategy in ("S", "C"):
            for name in ("box", "apple", "cylinder"):
                r = run_trial(args.hand, builtin_object(name), strategy, seed=1, planner=planner)  # type: ignore[arg-type]
                cells.append(f"{strategy}:{name}={'OK' if r.success else r.reason}")
        print(f"({point[0]:+.0f}, {point[1]:+.0f}) mm  " + " ".join(cells), flush=True)


if __name__ == "__main__":
    main()
