"""Objects as a camera sees them, timed side by side in one run (ratios, not seconds, are the figures to compare on
a shared machine):

- **registering** a cloud: its conservative solid (outlier filter + hull) from 100k points, and a 100k-vertex mesh
  object (its checks and principal axes), first time (cold, then cached by content);
- **planning** against the solid of a 100k-point cloud of the box versus against the box itself, same poses,
  alternated (target: within 2x);
- **segmenting** a 640 x 480 tabletop cloud rendered by the simulated depth camera (three objects) versus the same
  library calls run bare (scikit-learn's RANSAC and DBSCAN on the same points; target: within 2x).

Run: .venv/bin/python benchmarks/bench_objects.py [--rounds 5] [--plans 100]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np


def _best(f: Callable[[], object], rounds: int) -> float:
    """Median wall time [s] of ``rounds`` calls of ``f``."""
    times = []
    for _ in range(rounds):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def _seen_box(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    sx, sy, sz = 0.16, 0.06, 0.05
    top = np.c_[rng.uniform(-sx / 2, sx / 2, n // 2), rng.uniform(-sy / 2, sy / 2, n // 2), np.full(n // 2, sz)]
    front = np.c_[
        rng.uniform(-sx / 2, sx / 2, n - n // 2), np.full(n - n // 2, -sy / 2), rng.uniform(0, sz, n - n // 2)
    ]
    return np.vstack([top, front]) + np.array([0.5, 0.0, 0.0]) + rng.normal(0.0, 0.0005, (n, 3))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--plans", type=int, default=100)
    args = parser.parse_args()

    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()
    from softsig_service.objects import builtin_object, mesh
    from softsig_service.objects.cloud import conservative_solid
    from softsig_service.objects.parse import solid_object
    from softsig_service.planning.planner import Planner
    from softsig_service.planning.request import PlanRequest

    cloud = _seen_box(100_000)
    t_solid = _best(lambda: conservative_solid(cloud), args.rounds)
    t_hull = _best(lambda: conservative_solid(cloud, filter_outliers=False), args.rounds)
    rng = np.random.default_rng(1)
    u = rng.normal(size=(100_000, 3))
    sphere = u / np.linalg.norm(u, axis=1, keepdims=True) * 0.04 + [0, 0, 0.04]
    from scipy.spatial import ConvexHull

    hull = ConvexHull(sphere)  # a closed 100k-vertex mesh (every point is on the hull)
    faces = hull.simplices
    t_mesh = _best(lambda: mesh(sphere, faces, 0.2)._axes, 1)  # cold: checks and axes
    print(f"register: 100k-point cloud solid {t_solid * 1000:.0f} ms (hull alone {t_hull * 1000:.0f} ms, the "
          f"outlier filter the rest); 100k-vertex mesh object, cold {t_mesh * 1000:.0f} ms")  # fmt: skip

    seen = solid_object(conservative_solid(cloud), 0.0, 0.15, 1.0, "seen box")
    box = builtin_object("box")
    planner = Planner()
    poses = [(float(rng.uniform(0.4, 0.6)), float(rng.uniform(-0.15, 0.15)), float(rng.uniform(-3, 3)))
             for _ in range(args.plans)]  # fmt: skip
    for obj in (seen, box):  # models and worlds built before timing
        planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=obj, strategy="C"))
    t = {"box": [], "cloud": []}
    for x, y, yaw in poses:
        for name, obj in (("box", box), ("cloud", seen)):
            moved = obj.with_pose(x, y, yaw)
            t0 = time.perf_counter()
            planner.plan(PlanRequest(hand="pisa_iit_softhand", obj=moved, strategy="C"))
            t[name].append(time.perf_counter() - t0)
    pb, pc = statistics.median(t["box"]), statistics.median(t["cloud"])
    print(f"plan (C, SoftHand, {args.plans} poses, alternated): box p50 {pb * 1000:.2f} ms, solid of a 100k-point "
          f"cloud p50 {pc * 1000:.2f} ms: {pc / pb:.2f}x (target <= 2x)")  # fmt: skip

    from sklearn.cluster import DBSCAN
    from sklearn.linear_model import LinearRegression, RANSACRegressor

    from softsig_service.objects import cylinder
    from softsig_service.objects.segmentation import CLUSTER_DISTANCE, MIN_SAMPLES, PLANE_TOLERANCE, segment_tabletop
    from softsig_service.simulation.depth_camera import DepthCamera, depth_to_points, look_at, render_depth

    T = look_at([0.5, -0.45, 0.55], [0.5, 0.0, 0.0])
    scene = [builtin_object("box", yaw=0.3), cylinder(0.03, 0.12, 0.2, standing=True, x=0.5, y=0.16),
             builtin_object("apple", x=0.62, y=-0.12)]  # fmt: skip
    W = depth_to_points(render_depth(scene, T, DepthCamera())) @ T[:3, :3].T + T[:3, 3]

    def bare() -> None:
        r = RANSACRegressor(LinearRegression(), residual_threshold=PLANE_TOLERANCE, random_state=0, max_trials=200)
        r.fit(W[:, :2], W[:, 2])
        rest = W[~r.inlier_mask_]
        rest = rest[rest[:, 2] > r.predict(rest[:, :2]) + PLANE_TOLERANCE]
        DBSCAN(eps=CLUSTER_DISTANCE, min_samples=MIN_SAMPLES).fit_predict(rest)

    t_bare = _best(bare, args.rounds)
    t_seg = _best(lambda: segment_tabletop(W), args.rounds)
    t_seg_raw = _best(lambda: segment_tabletop(W, filter_outliers=False), args.rounds)
    print(f"segment a {len(W)}-point 640x480 tabletop (3 objects): softsig {t_seg * 1000:.0f} ms "
          f"({t_seg_raw * 1000:.0f} ms without the clusters' outlier filter), bare RANSAC + DBSCAN "
          f"{t_bare * 1000:.0f} ms: {t_seg / t_bare:.2f}x ({t_seg_raw / t_bare:.2f}x; target <= 2x)")  # fmt: skip


if __name__ == "__main__":
    main()
