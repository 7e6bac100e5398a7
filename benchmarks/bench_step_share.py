"""What share of a campaign worker's time MuJoCo's ``mj_step`` takes: the floor of what the campaign can gain
without fewer or cheaper physics steps.

Runs a random sample of the Table I grid's simulated trials (``--trials``, seed 0 of the shuffle) one after the
other in this process, as a campaign worker runs them (``run_trial_spec``), with every ``mj_step`` call of the
rollout, the approach replay and the ``clear_alone`` rule timed, and prints the wall time, the time in ``mj_step``
and its share, the steps and the time per step, and the sample's successes. The first trials of each cell also plan
and record their approach, as a worker's do.

``--set NAME=VALUE`` (repeatable) changes a MuJoCo option of the three scenes' models before any trial (``timestep``,
``ccd_tolerance``, ``iterations``, ``ls_iterations``, ``tolerance``, ``cone``: 0 pyramidal, 1 elliptic): what a
cheaper physics would buy, and, with ``--verdicts FILE`` (written) and ``--against FILE`` (a run's file to compare
with), how many of the sample's verdicts it changes. Such a change is a change of the simulation, not a speed-up of
it: the campaign runs the hands' own options.

Run: .venv/bin/python benchmarks/bench_step_share.py [--trials 150] [--hand pisa_iit_softhand_bracket]
     [--set timestep=0.0025] [--verdicts FILE] [--against FILE]
"""

from __future__ import annotations

import argparse
import json
import random
import time
from typing import Any

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()

import mujoco  # noqa: E402

from softsig_service.experiments.campaign import _plan_work, _worker_init, run_trial_spec  # noqa: E402
from softsig_service.experiments.campaign_spec import CampaignSpec  # noqa: E402
from softsig_service.experiments.trial import default_planner  # noqa: E402
from softsig_service.objects import builtin_object  # noqa: E402
from softsig_service.simulation import approach_replay, clear_alone, rollout  # noqa: E402
from softsig_service.simulation.scene import build_scene  # noqa: E402

OPTIONS = {"timestep": float, "ccd_tolerance": float, "iterations": int, "ls_iterations": int, "tolerance": float,
           "cone": int}  # fmt: skip


class TimedMujoco:
    """The ``mujoco`` module with ``mj_step`` timed (seconds and steps added up)."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.steps = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(mujoco, name)

    def mj_step(self, m: mujoco.MjModel, d: mujoco.MjData, nstep: int = 1) -> None:
        t0 = time.perf_counter()
        mujoco.mj_step(m, d, nstep)
        self.seconds += time.perf_counter() - t0
        self.steps += nstep


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=150)
    parser.add_argument("--hand", default="pisa_iit_softhand_bracket")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a MuJoCo option")
    parser.add_argument("--verdicts", help="write the sample's verdicts to this JSON file")
    parser.add_argument("--against", help="count the verdicts that differ from this file's")
    args = parser.parse_args()
    for item in args.set:
        name, _, value = item.partition("=")
        if name not in OPTIONS:
            parser.error(f"--set: unknown option {name!r} (one of {', '.join(OPTIONS)})")
        for obj in ("box", "apple", "cylinder"):  # the cached scenes every trial of this process uses
            setattr(build_scene(args.hand, builtin_object(obj), default_planner().settings, ()).model.opt, name,
                    OPTIONS[name](value))  # fmt: skip
    timed = TimedMujoco()
    for module in (rollout, approach_replay, clear_alone):
        module.mujoco = timed  # type: ignore[assignment]
    spec = CampaignSpec(hand=args.hand, trials=200, seed=7)
    _, todo, _ = _plan_work(spec.trial_specs(), {}, True)
    random.Random(0).shuffle(todo)
    sample = sorted(todo[: args.trials], key=lambda t: t.index)
    _worker_init()
    t0 = time.perf_counter()
    verdicts = {}
    for t in sample:
        r = run_trial_spec(t)
        verdicts[t.key] = [r["success"], r["reason"]]
    wall = time.perf_counter() - t0
    share = timed.seconds / wall
    print(f"{len(sample)} trials of the {args.hand} grid in one process: {wall:.2f} s")
    print(f"mj_step: {timed.seconds:.2f} s, {100 * share:.1f} % of it; {timed.steps} steps, "
          f"{1e6 * timed.seconds / timed.steps:.1f} us a step")  # fmt: skip
    print(
        f"successes: {sum(1 for v in verdicts.values() if v[0])} of {len(verdicts)}"
        + (f" ({', '.join(args.set)})" if args.set else "")
    )
    if args.verdicts:
        with open(args.verdicts, "w", encoding="utf-8") as f:
            json.dump(verdicts, f)
    if args.against:
        with open(args.against, encoding="utf-8") as f:
            other = json.load(f)
        shared = [k for k in verdicts if k in other]
        changed = sum(1 for k in shared if verdicts[k] != other[k])
        print(f"verdicts different from {args.against}: {changed} of {len(shared)}")


if __name__ == "__main__":
    main()
