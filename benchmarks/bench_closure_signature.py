"""Time the closure-signature methods on a synthetic closure (default 6 reference points x 500 frames).

Run:  .venv/bin/python benchmarks/bench_closure_signature.py [--frames 500] [--repeats 300] [--seed 0]

Prints the median and 95th percentile wall time [ms] of each call over ``--repeats`` runs (after warm-up), on
one core, for ``compute_closure_signature`` with each method, the per-frame ellipsoid series (an MVEE for
every frame) and a single MVEE. Target: <= 2 ms for the ellipsoid method on 6 points x 500 frames.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from softsig_service.geometry.ellipsoid import mvee
from softsig_service.hands.trajectory import ClosureTrajectory
from softsig_service.signatures.closure import compute_closure_signature, ellipsoid_axis_series


def synthetic_closure(n_frames: int, seed: int) -> ClosureTrajectory:
    """Thumb, four fingertips and the wrist of a hand curling its fingers about knuckles at z = 0.10 m [m]."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, n_frames)[:, None]
    knuckles_x = np.array([-0.03, -0.01, 0.01, 0.03])
    angle = 1.9 * s  # [rad], finger flexion
    length = 0.08  # [m], knuckle to tip
    fingers = np.stack(
        [
            np.broadcast_to(knuckles_x, angle.shape * np.array([1, 4])),
            length * np.sin(angle) * np.ones(4),
            0.10 + length * np.cos(angle) * np.ones(4),
        ],
        axis=-1,
    )  # (T, 4, 3)
    thumb = np.stack([-0.06 + 0.05 * s[:, 0], 0.03 + 0.02 * s[:, 0], 0.07 + 0.01 * s[:, 0]], axis=-1)[:, None]
    wrist = np.broadcast_to(np.array([0.0, -0.01, 0.02]), (n_frames, 1, 3))
    positions = np.concatenate([thumb, fingers, wrist], axis=1) + 2e-4 * rng.normal(size=(n_frames, 6, 3))
    return ClosureTrajectory(
        hand="synthetic",
        times=np.linspace(0.0, 1.0, n_frames),
        point_names=("thumb", "index", "middle", "ring", "little", "wrist"),
        positions=positions,
    )


def time_call(fn: Callable[[], object], repeats: int) -> NDArray[np.float64]:
    """Wall times [ms] of ``repeats`` calls after 3 warm-up calls."""
    for _ in range(3):
        fn()
    out = np.empty(repeats)
    for i in range(repeats):
        start = time.perf_counter_ns()
        fn()
        out[i] = (time.perf_counter_ns() - start) / 1e6
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    traj = synthetic_closure(args.frames, args.seed)
    cases: list[tuple[str, Callable[[], object], int]] = [
        ("ellipsoid (E_0, E_T)", lambda: compute_closure_signature(traj, "ellipsoid"), args.repeats),
        ("pca", lambda: compute_closure_signature(traj, "pca"), args.repeats),
        ("mesh (reference points)", lambda: compute_closure_signature(traj, "mesh"), args.repeats),
        (
            "ellipsoid series (all frames)",
            lambda: ellipsoid_axis_series(traj.positions),
            max(args.repeats // 10, 5),
        ),
        ("single MVEE (6 points)", lambda: mvee(traj.positions[0]), args.repeats),
    ]
    print(f"closure signature, {traj.n_points} points x {traj.n_frames} frames, numpy {np.__version__}")
    print(f"{'case':<32}{'median [ms]':>12}{'p95 [ms]':>10}{'repeats':>9}")
    for name, fn, repeats in cases:
        t = time_call(fn, repeats)
        print(f"{name:<32}{np.median(t):>12.3f}{np.percentile(t, 95):>10.3f}{repeats:>9d}")
    cs = compute_closure_signature(traj, "ellipsoid")
    print(
        f"ellipsoid CS ({cs.params['criterion']}): axis {np.round(cs.axis, 3).tolist()}, "
        f"magnitude {cs.magnitude:.4g} [{cs.extras['magnitude_unit']}], "
        f"distinctness {cs.distinctness:.2f}, iterations {cs.extras['solver']['initial']['iterations']}"
        f"/{cs.extras['solver']['final']['iterations']}"
    )


if __name__ == "__main__":
    main()
