"""The Table I campaign's wall time against an earlier revision, in one sitting, with the verdicts compared.

Runs the full grid (3 conditions x 3 objects x S and C x ``--trials`` per cell; 200 gives the 3600 trials of
docs/experiment_table1.md) from scratch in a temporary folder with ``--workers`` worker processes, first with the
package of git revision ``--baseline`` (exported beside the working tree, :mod:`baseline_tree`), then with the
working tree's, each in its own process. Prints both wall times and their ratio, what the working tree skipped
(trials recorded as replicas of an identical simulation, trials stopped early), every cell's successes with the
baseline's Wilson 95 % interval and whether the working tree's rate lies inside it, and how many trials (same
seeds) changed their verdict.

Run: .venv/bin/python benchmarks/bench_campaign.py [--trials 200] [--workers 2] [--baseline 106e8e9]
     [--hand pisa_iit_softhand] [--baseline-hand NAME] [--objects box,apple,cylinder]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from baseline_tree import export_revision, tree_env
from scipy.stats import binomtest

CHILD = """
import json, sys, time
from pathlib import Path
from softsig_service.gl_backend import prepare_mujoco
prepare_mujoco()
import softsig_service
from softsig_service.experiments.campaign import run_campaign
from softsig_service.experiments.campaign_spec import CampaignSpec

def main():
    hand, trials, workers, out, objects = sys.argv[1:6]
    spec = CampaignSpec(hand=hand, trials=int(trials), seed=7, objects=tuple(objects.split(",")))
    t0 = time.perf_counter()
    result = run_campaign(spec, Path(out), workers=int(workers))
    wall = time.perf_counter() - t0
    keep = ("key", "object", "strategy", "sigma_r", "sigma_t", "success", "reason")
    records = [{k: r.get(k) for k in keep} | {"same_as": r.get("same_as"),
               "stopped": bool((r.get("diagnosis") or {}).get("stopped"))} for r in result.records]
    print(json.dumps({"wall": wall, "package": softsig_service.__file__, "records": records}))

if __name__ == "__main__":
    main()
"""


def run(tree: Path | None, args: argparse.Namespace, tmp: Path, name: str, hand: str) -> dict:
    script = tmp / f"{name}_campaign.py"
    script.write_text(CHILD, encoding="utf-8")
    env, cwd = tree_env(tree)
    out = subprocess.run(
        [sys.executable, str(script), hand, str(args.trials), str(args.workers), str(tmp / name), args.objects],
        env=env, cwd=cwd, check=True, capture_output=True, text=True,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def cells(records: list[dict]) -> dict[tuple, list[bool]]:
    out: dict[tuple, list[bool]] = {}
    for r in records:
        out.setdefault((r["sigma_r"], r["sigma_t"], r["object"], r["strategy"]), []).append(bool(r["success"]))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=200, help="trials per cell")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--baseline", default="106e8e9", help="git revision to compare against")
    parser.add_argument("--hand", default="pisa_iit_softhand")
    parser.add_argument(
        "--baseline-hand",
        default=None,
        help="the hand's name in the baseline revision, where it differs (the bracket SoftHand was "
        "pisa_iit_softhand before e1a27a1: --hand pisa_iit_softhand_bracket --baseline-hand pisa_iit_softhand)",
    )
    parser.add_argument("--objects", default="box,apple,cylinder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        base_tree = export_revision(args.baseline, tmp / "baseline")
        base = run(base_tree, args, tmp, "baseline", args.baseline_hand or args.hand)
        new = run(None, args, tmp, "working", args.hand)
    assert str(base_tree) in base["package"] and str(base_tree) not in new["package"]
    n = len(new["records"])
    print(f"== Table I grid, {args.hand}, {args.trials} per cell ({n} trials), {args.workers} workers, seed 7")
    print(f"baseline {args.baseline}: {base['wall']:7.1f} s")
    print(f"working tree: {new['wall']:7.1f} s  -> {base['wall'] / new['wall']:.2f}x faster")
    replicas = sum(1 for r in new["records"] if r["same_as"])
    stopped = sum(1 for r in new["records"] if r["stopped"] and not r["same_as"])
    print(f"working tree: {n - replicas} simulated, {replicas} replicas of an identical simulation, "
          f"{stopped} simulated trials stopped early")  # fmt: skip
    old_cells, new_cells = cells(base["records"]), cells(new["records"])
    print(f"{'sigma_r':>7s} {'sigma_t':>7s} {'object':9s} {'str':3s} {'baseline':>8s} {'95 % interval':>15s} "
          f"{'working':>7s} inside")  # fmt: skip
    inside_all = True
    for key in sorted(old_cells):
        old, cur = old_cells[key], new_cells[key]
        ci = binomtest(sum(old), len(old)).proportion_ci(method="wilson")
        inside = ci.low <= sum(cur) / len(cur) <= ci.high
        inside_all &= inside
        print(f"{key[0]:7.2f} {key[1]:7.3f} {key[2]:9s} {key[3]:3s} {sum(old):4d}/{len(old):<3d} "
              f"[{ci.low:.3f}, {ci.high:.3f}] {sum(cur):4d}/{len(cur):<3d} {'yes' if inside else 'NO'}")  # fmt: skip
    verdict = {r["key"]: (r["success"], r["reason"]) for r in base["records"]}
    changed = [r["key"] for r in new["records"] if (r["success"], r["reason"]) != verdict[r["key"]]]
    print(f"every cell inside the baseline's 95 % interval: {inside_all}")
    print(f"trials whose verdict (success, reason) changed: {len(changed)} of {n} {changed[:10]}")


if __name__ == "__main__":
    main()
