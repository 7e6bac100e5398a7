"""UR5 IK and collision-check figures: latency percentiles [ms], IK success rate.

Run from the repository root:  ``.venv/bin/python benchmarks/bench_ur5.py [--n 1000] [--seed 0]``

Targets are reachable by construction: a random configuration within the joint limits (restricted to
[-pi, pi] per joint), its flange pose by FK, then IK solved

* "good seed": from the true configuration plus N(0, 0.05 rad) noise per joint (a planner's warm start);
* "other q": from another random configuration as ``current_q`` (the robot elsewhere);
* "no current_q": without ``current_q``;
* "exhaustive": every seed group run, the closest solution kept.

Each case runs with the default solver (closed-form UR branches polished by the numeric solver) and with
``analytic=False`` ("numeric only": current_q, then 8 random seeds).

Collision checks use a hand of 3 primitives and a box object near the flange (not touching).

"IK vs ur-analytic-ik" times the warm-start case per pose [us] against a closed-form peer, `ur-analytic-ik
<https://pypi.org/project/ur-analytic-ik/>`_ (C++ with Python bindings; a benchmark-only dependency, never
imported by the library): ``.venv/bin/pip install -e '.[bench]'`` (or ``pip install ur-analytic-ik==0.1.0.post3``);
without it the comparison is skipped, saying so. Both solve the same poses in the same run: ``solve_ik`` (and the
service's ``solve_ik_unchecked``) from ``current_q`` = the true configuration + N(0, 0.05 rad), the peer's
``ur5.inverse_kinematics_closest`` from the same ``current_q`` (its pose in the DH base frame, ``Rz(pi)
T_base_link_tool0``, converted before timing). Each pass runs every pose once; the figure is the best of the
passes' means. The peer's solutions are then checked by FK on the same model, wrapped into the joint limits nearest
``current_q`` like softsig's, and the nearest one compared with softsig's answer. Only this section:
``.venv/bin/python benchmarks/bench_ur5.py --vs-peer [--n 2000] [--passes 7]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from softsig_service.arm.collision import CollisionWorld
from softsig_service.arm.shapes import HandShape, ObjectShape
from softsig_service.arm.ur5 import POSITION_TOLERANCE, ROTATION_TOLERANCE, UR5, IKResult, load_ur5
from softsig_service.geometry.transforms import apply, make_transform, rot_x, rot_z


def percentiles(samples: list[float]) -> tuple[float, float, float]:
    """p50, p95, max of latencies given in [s], returned in [ms]."""
    a = np.array(samples) * 1e3
    return float(np.percentile(a, 50)), float(np.percentile(a, 95)), float(a.max())


def ik_case(
    ur5: UR5,
    n: int,
    seed: int,
    start: Callable[[np.ndarray, np.random.Generator], np.ndarray | None],
    **kw: object,
) -> tuple[list[float], int, int, float]:
    """Latencies [s], successes, failures that are within limits, mean iterations."""
    rng = np.random.default_rng(seed)
    lat: list[float] = []
    ok = 0
    iters = 0
    for k in range(n):
        q_true = ur5.random_configuration(rng)
        target = ur5.fk(q_true)
        q0 = start(q_true, rng)
        t0 = time.perf_counter()
        res: IKResult = ur5.solve_ik(target, q0, rng_seed=k, **kw)  # type: ignore[arg-type]
        lat.append(time.perf_counter() - t0)
        iters += res.iterations
        if res.success:
            dp, dr = UR5.pose_error(ur5.fk(res.q), target)
            if dp <= 1e-5 and dr <= 1e-4 and ur5.within_limits(res.q):
                ok += 1
    return lat, ok, n, iters / n


_RZ_PI = np.diag([-1.0, -1.0, 1.0, 1.0])
"""``T_dh_base_link``: the DH base frame (the peer's) is ``base_link`` turned by pi about z."""


def ik_vs_peer(ur5: UR5, n: int, seed: int, passes: int) -> list[str]:
    """Warm-start IK per pose [us], softsig against ur-analytic-ik on the same poses; report lines (a single
    line saying why when the peer is not installed)."""
    try:
        from ur_analytic_ik import ur5 as peer
    except ImportError:
        return [
            "IK vs ur-analytic-ik: skipped, ur-analytic-ik is not installed "
            "(.venv/bin/pip install -e '.[bench]', or pip install ur-analytic-ik==0.1.0.post3)"
        ]
    rng = np.random.default_rng(seed)
    q_true = [ur5.random_configuration(rng) for _ in range(n)]
    targets = [ur5.fk(q) for q in q_true]
    starts = [q + rng.normal(0.0, 0.05, 6) for q in q_true]
    targets_dh = [np.ascontiguousarray(_RZ_PI @ T) for T in targets]
    cases = list(zip(targets, starts, strict=True))
    cases_dh = list(zip(targets_dh, starts, strict=True))
    jobs: dict[str, Callable[[], object]] = {
        "softsig solve_ik": lambda: [ur5.solve_ik(T, q0) for T, q0 in cases],
        "softsig solve_ik_unchecked": lambda: [ur5.solve_ik_unchecked(T, q0) for T, q0 in cases],
        "ur-analytic-ik closest": lambda: [peer.inverse_kinematics_closest(T, *q0) for T, q0 in cases_dh],
    }
    best = dict.fromkeys(jobs, math.inf)
    for _ in range(passes):  # interleaved, so that a busy moment of the machine hits every solver alike
        for name, job in jobs.items():
            t0 = time.perf_counter()
            job()
            best[name] = min(best[name], (time.perf_counter() - t0) / n)

    # the same task: each peer solution checked by FK on the model, wrapped into the limits nearest current_q
    same = peer_ok = closest_same = 0
    worst_soft = [0.0, 0.0]
    worst_peer = [0.0, 0.0]
    for T, T_dh, q0 in zip(targets, targets_dh, starts, strict=True):
        res = ur5.solve_ik(T, q0)
        worst_soft = [max(worst_soft[0], res.position_residual), max(worst_soft[1], res.rotation_residual)]
        valid = []
        for s in peer.inverse_kinematics(T_dh):
            dp, dr = UR5.pose_error(ur5.fk(s), T)
            w = ur5.wrap_to_limits(s, q0)
            if w is not None and dp <= POSITION_TOLERANCE and dr <= ROTATION_TOLERANCE:
                valid.append((float(np.linalg.norm(w - q0)), w, dp, dr))
        if not valid:
            continue
        peer_ok += 1
        _, q_peer, dp, dr = min(valid, key=lambda v: v[0])
        worst_peer = [max(worst_peer[0], dp), max(worst_peer[1], dr)]
        same += bool(res.success and np.max(np.abs(res.q - q_peer)) < 1e-6)
        closest = peer.inverse_kinematics_closest(T_dh, *q0)
        closest_same += bool(closest and np.max(np.abs(closest[0] - q_peer)) < 1e-6)
    us = {name: t * 1e6 for name, t in best.items()}
    peer_us = us["ur-analytic-ik closest"]
    lines = [f"IK vs ur-analytic-ik, warm start (current_q = true q + N(0, 0.05 rad)), {n} poses, best of {passes}:"]
    for name, t_us in us.items():
        lines.append(f"  {name:28s} {t_us:8.2f} us/pose  ratio to the peer {t_us / peer_us:5.2f}")
    lines.append(
        f"  same answer: softsig's q = the peer's FK-checked solution nearest current_q (in the limits) in "
        f"{same}/{peer_ok} poses ({n - peer_ok} without a peer solution); the peer's own closest pick agrees in "
        f"{closest_same}/{peer_ok}"
    )
    lines.append(
        f"  worst residuals: softsig {worst_soft[0]:.1e} m, {worst_soft[1]:.1e} rad; the peer's "
        f"{worst_peer[0]:.1e} m, {worst_peer[1]:.1e} rad (tolerances {POSITION_TOLERANCE:g} m, "
        f"{ROTATION_TOLERANCE:g} rad)"
    )
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=1000, help="random reachable targets per IK case")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--passes", type=int, default=7, help="timing passes of the peer comparison (best kept)")
    ap.add_argument("--vs-peer", action="store_true", help="only the comparison with ur-analytic-ik")
    args = ap.parse_args()

    t0 = time.perf_counter()
    ur5 = load_ur5()
    t_load = time.perf_counter() - t0
    if args.vs_peer:
        print("\n".join(ik_vs_peer(ur5, args.n, args.seed, args.passes)))
        return

    rows: list[tuple[str, float, float, float, str]] = []
    cases: list[tuple[str, Callable[[np.ndarray, np.random.Generator], np.ndarray | None], dict[str, object]]]

    def good(q: np.ndarray, r: np.random.Generator) -> np.ndarray | None:
        return q + r.normal(0.0, 0.05, 6)

    def other(q: np.ndarray, r: np.random.Generator) -> np.ndarray | None:
        return ur5.random_configuration(r)

    def nothing(q: np.ndarray, r: np.random.Generator) -> np.ndarray | None:
        return None

    cases = [
        ("IK good seed", good, {}),
        ("IK from other q", other, {}),
        ("IK no current_q", nothing, {}),
        ("IK from other q, exhaustive", other, {"exhaustive": True}),
        ("numeric only: good seed", good, {"analytic": False}),
        ("numeric only: other q, 8 seeds", other, {"analytic": False}),
        ("numeric only: no current_q", nothing, {"analytic": False}),
        ("numeric only: exhaustive", other, {"analytic": False, "exhaustive": True}),
    ]
    for name, start, kw in cases:
        ik_case(ur5, 20, args.seed + 99, start, **kw)  # warm-up
        lat, ok, n, it = ik_case(ur5, args.n, args.seed, start, **kw)
        p50, p95, mx = percentiles(lat)
        rows.append((name, p50, p95, mx, f"success {ok}/{n} = {100.0 * ok / n:.1f} %, {it:.1f} iterations"))

    # unreachable targets: beyond the reach ball (instant) and just inside it (every seed runs)
    for name, x, analytic in (
        ("IK unreachable, 3 m", 3.0, True),
        ("IK unreachable, 1.05 m", 1.05, True),
        ("numeric only: unreachable, 1.05 m", 1.05, False),
    ):
        target = make_transform(rot_x(math.pi), [x, 0.0, 0.09])
        lat = []
        for k in range(50):
            t1 = time.perf_counter()
            res = ur5.solve_ik(target, np.zeros(6), rng_seed=k, analytic=analytic)
            lat.append(time.perf_counter() - t1)
            assert not res.success and res.reason == "unreachable"
        p50, p95, mx = percentiles(lat)
        rows.append((name, p50, p95, mx, f"reason {res.reason!r}"))

    hand = [
        HandShape("box", (0.04, 0.05, 0.02), make_transform(None, [0.0, 0.0, 0.02]), name="palm"),
        HandShape("capsule", (0.01, 0.03), make_transform(None, [0.0, 0.035, 0.08]), name="finger_a"),
        HandShape("capsule", (0.01, 0.03), make_transform(None, [0.0, -0.035, 0.08]), name="finger_b"),
    ]
    t1 = time.perf_counter()
    world = CollisionWorld(ur5, hand)
    t_world = time.perf_counter() - t1
    q = ur5.solve_ik(
        make_transform(rot_z(0.3) @ rot_x(math.pi), [0.5, 0.1, 0.3]), np.array([0, -1.2, 1.5, -1.9, -1.57, 0])
    ).q
    T = ur5.fk(q)
    world.set_object(ObjectShape("box", (0.08, 0.03, 0.025)), make_transform(None, apply(T, [0.0, 0.0, 0.25])))
    rng = np.random.default_rng(args.seed)
    qs = [ur5.random_configuration(rng) for _ in range(args.n)]
    for name, fn in (
        ("collision check (distances)", lambda qq: world.check(qq)),
        ("collision check (no distances)", lambda qq: world.check(qq, distances=False)),
        ("collision check_path 10 steps", lambda qq: world.check_path(q, qq, 10, stop_at_first=False)),
    ):
        for qq in qs[:20]:
            fn(qq)
        lat = []
        hits = 0
        for qq in qs:
            t1 = time.perf_counter()
            rep = fn(qq)
            lat.append(time.perf_counter() - t1)
            hits += rep.in_collision
        p50, p95, mx = percentiles(lat)
        rows.append((name, p50, p95, mx, f"{hits}/{len(qs)} random q in collision, {len(world.pair_names)} pairs"))
    t1 = time.perf_counter()
    for _ in range(100):
        world.set_object(ObjectShape("box", (0.08, 0.03, 0.025)), make_transform(None, apply(T, [0, 0, 0.25])))
    t_set = (time.perf_counter() - t1) / 100

    print(
        f"UR5 model load {t_load * 1e3:.1f} ms; CollisionWorld build {t_world * 1e3:.1f} ms (first one: "
        f"hulls); set_object {t_set * 1e3:.2f} ms; n = {args.n}, seed = {args.seed}"
    )
    print(f"{'case':34s} {'p50 [ms]':>9s} {'p95 [ms]':>9s} {'max [ms]':>9s}  notes")
    print("-" * 110)
    for name, p50, p95, mx, note in rows:
        print(f"{name:34s} {p50:9.3f} {p95:9.3f} {mx:9.3f}  {note}")
    print()
    print("\n".join(ik_vs_peer(ur5, args.n, args.seed, args.passes)))


if __name__ == "__main__":
    main()
