"""What share of a campaign worker's time MuJoCo's ``mj_step`` takes: the floor of what the campaign can gain
without fewer or cheaper physics steps.

Runs a random sample of the Table I grid's simulated trials (``--trials``, seed 0 of the shuffle) one after the
other in this process, as a campaign worker runs them (``run_trial_spec``), with every ``mj_step`` call of the
rollout, the approach replay and the ``clear_alone`` rule timed, and prints the wall time, the time in ``mj_step``
and its share, the steps and the time per step. The first trials of each cell also plan and record their approach,
as a worker's do.

Run: .venv/bin/python benchmarks/bench_step_share.py [--trials 150] [--hand pisa_iit_softhand_bracket]
"""

from __future__ import annotations

import argparse
import random
import time
from typing import Any

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()

import mujoco  # noqa: E402

from softsig_service.experiments.campaign import _plan_work, _worker_init, run_trial_spec  # noqa: E402
from softsig_service.experiments.campaign_spec import CampaignSpec  # noqa: E402
from softsig_service.simulation import approach_replay, clear_alone, rollout  # noqa: E402


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
    args = parser.parse_args()
    timed = TimedMujoco()
    for module in (rollout, approach_replay, clear_alone):
        module.mujoco = timed  # type: ignore[assignment]
    spec = CampaignSpec(hand=args.hand, trials=200, seed=7)
    _, todo, _ = _plan_work(spec.trial_specs(), {}, True)
    random.Random(0).shuffle(todo)
    sample = sorted(todo[: args.trials], key=lambda t: t.index)
    _worker_init()
    t0 = time.perf_counter()
    for t in sample:
        run_trial_spec(t)
    wall = time.perf_counter() - t0
    share = timed.seconds / wall
    print(f"{len(sample)} trials of the {args.hand} grid in one process: {wall:.2f} s")
    print(f"mj_step: {timed.seconds:.2f} s, {100 * share:.1f} % of it; {timed.steps} steps, "
          f"{1e6 * timed.seconds / timed.steps:.1f} us a step")  # fmt: skip


if __name__ == "__main__":
    main()
