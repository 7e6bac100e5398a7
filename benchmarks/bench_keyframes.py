"""What a keyframe strip costs: a trial's wall time without and with ``--frames`` (the strip rendered and written),
side by side in one run.

Per hand and object: ``--n`` trials under the largest Table I uncertainty (0.2 rad, 0.02 m, strategy C), each run
twice in turn, without and with a :class:`~softsig_service.simulation.keyframes.KeyframeRecorder` (same seed, same
outcome), models and renderer built before timing. Printed: the median wall time [s] of a trial without and with
the strip (including its PNG written to a temporary folder), the median extra time [s] and its split (the renders at
the phase boundaries; the composition and the PNG), the ratio, and the median strip size [kB].

Run: MUJOCO_GL=egl .venv/bin/python benchmarks/bench_keyframes.py [--n 10] [--hands parallel_gripper,pisa_iit_softhand]
     [--objects box,apple,cylinder]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()

from softsig_service.experiments.campaign_spec import trial_seed  # noqa: E402
from softsig_service.experiments.trial import run_trial  # noqa: E402
from softsig_service.objects import builtin_object  # noqa: E402
from softsig_service.simulation.keyframes import KeyframeRecorder  # noqa: E402


def bench(hand: str, obj_name: str, n: int, folder: Path) -> None:
    obj = builtin_object(obj_name)
    recorder = KeyframeRecorder()
    try:
        warm = run_trial(hand, obj, "C", seed=0, on_phase=recorder)  # models, planner, renderer, matplotlib
        recorder.save_trial(folder, 0, warm, "warm-up")
        plain, framed, renders, strips, sizes, ok = [], [], [], [], [], 0
        for k in range(n):
            seed = trial_seed(1, (), k)
            t0 = time.perf_counter()
            a = run_trial(hand, obj, "C", seed=seed, sigma_r=0.2, sigma_t=0.02)
            plain.append(time.perf_counter() - t0)
            before = recorder.seconds
            t0 = time.perf_counter()
            b = run_trial(hand, obj, "C", seed=seed, sigma_r=0.2, sigma_t=0.02, on_phase=recorder)
            rendered = recorder.seconds - before
            path = recorder.save_trial(folder, k, b, f"{hand} / {obj_name} / C")
            framed.append(time.perf_counter() - t0)
            renders.append(rendered)
            strips.append(recorder.seconds - before - rendered)
            sizes.append(path.stat().st_size / 1000.0)
            assert (a.success, a.reason) == (b.success, b.reason), "the strip changed the outcome"
            ok += a.success
    finally:
        recorder.close()
    p, f = statistics.median(plain), statistics.median(framed)
    extra = statistics.median([y - x for x, y in zip(plain, framed, strict=True)])
    print(
        f"{hand:18s} {obj_name:9s} {p:7.3f} {f:7.3f} {extra:7.3f} {statistics.median(renders):7.3f} "
        f"{statistics.median(strips):7.3f} {f / p:6.1f} {statistics.median(sizes):6.0f} {ok:3d}/{n}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=10, help="trials per hand and object")
    parser.add_argument("--hands", default="parallel_gripper,pisa_iit_softhand")
    parser.add_argument("--objects", default="box,apple,cylinder")
    args = parser.parse_args()
    print(f"== a trial without and with its keyframe strip: strategy C, sigma 0.2 rad / 0.02 m, {args.n} per row")
    print(
        f"{'hand':18s} {'object':9s} {'plain':>7s} {'strip':>7s} {'extra':>7s} {'render':>7s} {'compose':>7s} "
        f"{'ratio':>6s} {'kB':>6s} {'ok':>6s}   (medians [s])"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for hand in (h.strip() for h in args.hands.split(",") if h.strip()):
            for obj in (o.strip() for o in args.objects.split(",") if o.strip()):
                bench(hand, obj, args.n, Path(tmp))


if __name__ == "__main__":
    main()
