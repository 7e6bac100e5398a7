"""Wall time of one free-space closure simulation per built-in hand, and MuJoCo steps per second.

Run: .venv/bin/python benchmarks/bench_closure_simulation.py [--repeats N]
"""

from __future__ import annotations

import argparse
import statistics
import time

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()

from softsig_service.hands.closure import simulate_closure  # noqa: E402
from softsig_service.hands.model import builtin_hand_names, load_hand  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=10)
    args = parser.parse_args()
    print(
        f"{'hand':20s} {'steps':>6s} {'points':>6s} {'median [ms]':>12s} {'p95 [ms]':>9s} {'steps/s':>9s}"
        f" {'w/ surface [ms]':>16s}"
    )
    for name in builtin_hand_names():
        hand = load_hand(name)
        man = hand.manifest
        steps = round((man.closure.duration + man.closure.settle) / man.simulation.timestep)
        simulate_closure(hand, surface_points=0)  # warm-up
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            simulate_closure(hand, surface_points=0)
            times.append(time.perf_counter() - t0)
        surf = []
        for _ in range(max(1, args.repeats // 2)):
            t0 = time.perf_counter()
            simulate_closure(hand)
            surf.append(time.perf_counter() - t0)
        med = statistics.median(times)
        p95 = sorted(times)[max(0, round(0.95 * len(times)) - 1)]
        print(
            f"{name:20s} {steps:6d} {len(hand.points):6d} {med * 1e3:12.1f} {p95 * 1e3:9.1f} {steps / med:9.0f}"
            f" {statistics.median(surf) * 1e3:16.1f}"
        )


if __name__ == "__main__":
    main()
