"""Validation speed: wall time per trial, real-time factor, where a trial's time goes, and a campaign's wall time.

1. Per trial, in this process, models built before timing (as a campaign worker has them after its first
   trial): wall time p50/p95 [s] per (object, strategy) under the largest Table I uncertainty
   (0.2 rad, 0.02 m), the split plan / IK of the approach and lift lines / simulation, and the real-time
   factor (sim time / wall time). Target: one trial <= 0.2 s wall.
2. Inside the simulation: MuJoCo's own timers (``MjData.timer``) of one trial per object: the share of the step
   spent in collision detection, the constraint solver and the rest, and the time per step [us].
3. The full Table I campaign (3 conditions x 3 objects x 2 strategies x ``--campaign-trials``) from scratch
   in a temporary folder with 1 worker (in-process) and with 2 worker processes (spawn; includes their start-up
   and model building).

Run: .venv/bin/python benchmarks/bench_validation.py [--n 10] [--hand pisa_iit_softhand] [--campaign-trials 20]
     [--skip-campaign]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any, Literal

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()

import mujoco  # noqa: E402

from softsig_service.experiments.campaign import run_campaign  # noqa: E402
from softsig_service.experiments.campaign_spec import CampaignSpec, trial_seed  # noqa: E402
from softsig_service.experiments.trial import run_trial  # noqa: E402
from softsig_service.objects import BUILTIN_NAMES, builtin_object  # noqa: E402

STRATEGIES: tuple[Literal["S", "C"], ...] = ("S", "C")


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(q * (len(s) - 1)))]


def per_trial(hand: str, n: int) -> None:
    print(f"== per trial: {hand}, {n} trials per cell, sigma_r 0.2 rad, sigma_t 0.02 m, in-process")
    for name in BUILTIN_NAMES:  # build the models first
        for s in STRATEGIES:
            run_trial(hand, builtin_object(name), s, seed=0)
    print(
        f"{'object':9s} {'str':3s} {'p50 [s]':>8s} {'p95 [s]':>8s} {'plan':>6s} {'IK':>6s} {'sim':>6s} "
        f"{'RTF':>5s} {'ok':>3s}  (medians [s])"
    )
    all_wall: list[float] = []
    for name in BUILTIN_NAMES:
        for s in STRATEGIES:
            wall, plan, ik, sim, rtf, ok = [], [], [], [], [], 0
            for k in range(n):
                r = run_trial(
                    hand,
                    builtin_object(name),
                    s,
                    seed=trial_seed(1, (), k),
                    sigma_r=0.2,
                    sigma_t=0.02,
                )
                wall.append(r.wall_time)
                plan.append(r.timing.get("plan", 0.0))
                ik.append(r.timing.get("ik", 0.0))
                sim.append(r.timing.get("sim", 0.0))
                rtf.append(r.sim_time / r.wall_time)
                ok += r.success
            all_wall += wall
            med = [statistics.median(v) for v in (plan, ik, sim, rtf)]
            print(
                f"{name:9s} {s:3s} {pct(wall, 0.5):8.3f} {pct(wall, 0.95):8.3f} {med[0]:6.3f} {med[1]:6.3f} "
                f"{med[2]:6.3f} {med[3]:5.1f} {ok:3d}"
            )
    mean = statistics.mean(all_wall)
    print(f"all: p50 {pct(all_wall, 0.5):.3f} s, p95 {pct(all_wall, 0.95):.3f} s, mean {mean:.3f} s")


def step_breakdown(hand: str) -> None:
    print(f"== inside the simulation (MuJoCo timers, one nominal C trial per object, {hand})")
    names = {
        "step": mujoco.mjtTimer.mjTIMER_STEP,
        "collision": mujoco.mjtTimer.mjTIMER_POS_COLLISION,
        "make constraints": mujoco.mjtTimer.mjTIMER_POS_MAKE,
        "constraint solver": mujoco.mjtTimer.mjTIMER_CONSTRAINT,
        "kinematics": mujoco.mjtTimer.mjTIMER_POS_KINEMATICS,
        "inertia": mujoco.mjtTimer.mjTIMER_POS_INERTIA,
    }
    for name in BUILTIN_NAMES:
        captured: dict[str, Any] = {}

        def grab(scene: Any, data: Any, captured: dict[str, Any] = captured) -> None:
            captured.setdefault("data", data)
            captured.setdefault("scene", scene)

        run_trial(hand, builtin_object(name), "C", seed=0, on_frame=grab, frame_period=1e9)
        data = captured["data"]
        step = data.timer[names["step"]]
        total = step.duration
        parts = ", ".join(f"{k} {100 * data.timer[v].duration / total:4.1f} %" for k, v in names.items() if k != "step")
        print(
            f"{name:9s} {step.number} steps, {1e6 * total / max(step.number, 1):6.1f} us/step; {parts}; "
            f"nv {captured['scene'].model.nv}, max contacts {data.maxuse_con}"
        )


def campaign(hand: str, trials: int) -> None:
    print(f"== full Table I campaign: {hand}, {trials} trials per cell ({3 * 3 * 2 * trials} trials), from scratch")
    spec = CampaignSpec(hand=hand, trials=trials, seed=0)
    outcomes: dict[int, list[tuple[str, bool]]] = {}
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            result = run_campaign(spec, Path(tmp), workers=workers)
            wall = time.perf_counter() - t0
        n = len(result.records)
        outcomes[workers] = [(r["key"], r["success"]) for r in result.records]
        print(
            f"workers {workers}: {wall:7.1f} s wall, {wall / n:.3f} s per trial, "
            f"{sum(r['success'] for r in result.records)}/{n} successes"
        )
    print("same outcomes with 1 and 2 workers:", outcomes[1] == outcomes[2])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=10, help="trials per (object, strategy) for the per-trial times")
    parser.add_argument("--hand", default="pisa_iit_softhand")
    parser.add_argument("--campaign-trials", type=int, default=20, help="trials per cell of the campaign")
    parser.add_argument("--skip-campaign", action="store_true")
    args = parser.parse_args()
    per_trial(args.hand, args.n)
    step_breakdown(args.hand)
    if not args.skip_campaign:
        campaign(args.hand, args.campaign_trials)


if __name__ == "__main__":
    main()
