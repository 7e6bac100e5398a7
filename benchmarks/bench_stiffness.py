"""Wall time of the stiffness signature per built-in hand: K (grasp + matrices + math, and the math alone) and
the pull test per direction.

Run: .venv/bin/python benchmarks/bench_stiffness.py [--object apple] [--repeats 5] [--directions 26]

Columns: ``grasp+K`` = grasp_object + grasp_matrices + grasp_stiffness_from_matrices (median of the repeats);
``K math`` = grasp_stiffness_from_matrices alone on the same matrices (median of 200 calls); ``pull/dir`` =
quasi-static pull test per direction (mean and max over the directions, one run each; 0 when the hand does not
hold the object alone, since nothing is simulated); ``ramp/dir`` = the 50 N/s ramp mode, mean per direction.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()

from softsig_service.hands.model import builtin_hand_names, load_hand  # noqa: E402
from softsig_service.simulation.grasp import grasp_object  # noqa: E402
from softsig_service.simulation.grasp_matrices import grasp_matrices, grasp_stiffness_from_matrices  # noqa: E402
from softsig_service.simulation.pullout import PullSettings, default_directions, pull_test  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--object", default="apple", help="built-in object: apple, box or cylinder")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--directions", type=int, default=26, help="first N of the 26 default directions")
    args = parser.parse_args()
    D = default_directions()[: args.directions]
    print(f"object: {args.object}; directions: {len(D)}; repeats: {args.repeats}")
    print(
        f"{'hand':20s} {'held':>5s} {'nc':>3s} {'grasp+K [ms]':>13s} {'K math [ms]':>12s} "
        f"{'pull/dir mean [ms]':>19s} {'max [ms]':>9s} {'ramp/dir [ms]':>14s} {'k_t [N/m]':>24s}"
    )
    for name in builtin_hand_names():
        hand = load_hand(name)
        grasp_object(hand, args.object)  # warm-up (model compilation paths, caches)
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            grasp = grasp_object(hand, args.object)
            mats = grasp_matrices(grasp)
            terms = grasp_stiffness_from_matrices(mats)
            times.append(time.perf_counter() - t0)
        math_times = []
        for _ in range(200):
            t0 = time.perf_counter()
            grasp_stiffness_from_matrices(mats)
            math_times.append(time.perf_counter() - t0)
        pulls = []
        for d in D:
            t0 = time.perf_counter()
            pull_test(grasp, d)
            pulls.append(time.perf_counter() - t0)
        ramps = []
        for d in D:
            t0 = time.perf_counter()
            pull_test(grasp, d, PullSettings(mode="ramp"))
            ramps.append(time.perf_counter() - t0)
        kt = np.linalg.eigvalsh(terms.K[:3, :3])[::-1]
        kt_s = "/".join(f"{v:.0f}" for v in kt)
        print(
            f"{name:20s} {grasp.held!s:>5s} {len(mats.contacts):3d} {statistics.median(times) * 1e3:13.1f} "
            f"{statistics.median(math_times) * 1e3:12.3f} {statistics.mean(pulls) * 1e3:19.1f} "
            f"{max(pulls) * 1e3:9.1f} {statistics.mean(ramps) * 1e3:14.1f} {kt_s:>24s}"
        )


if __name__ == "__main__":
    main()
