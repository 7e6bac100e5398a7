"""Top-grasp plan latency in-process: p50/p95 [ms] for strategies S and C on the three built-in objects, and for
mesh objects of growing size; optionally beside an earlier revision of the planner, with the joint differences.

Objects are placed at random reachable table poses (x in [0.35, 0.6] m, y in [-0.25, 0.25] m, any yaw) from a
fixed seed; models are built before timing (as the service does at start-up). The split columns show where
the time goes: the strategy (C: the CasADi NLP, both yaw branches), UR5 IK (grasp for both branches, pre-grasp
and approach waypoints of the chosen one) and collision work (descent along the approach + coal checks).
``cpu`` is the plan's own thread CPU time: on a shared machine the wall-clock figures include time the process
waited for a core, the CPU figures do not.

``--baseline REV`` runs this same script against the package at git revision ``REV`` (exported with
``git archive`` to a temporary folder) and against the working tree, in separate processes, ``--rounds`` times
in turn (A B A B ...), then prints both and the largest joint difference between their plans.

``--mesh-vertices N [N ...]`` adds the curve for a mesh object (an ellipsoid of radii 50 x 35 x 35 mm, UV
sphere with about N vertices): the first plan of the mesh (cold: its hull and principal axes are built) and
p50/p95 of the following ones at random poses, beside the box's p50.

Run: .venv/bin/python benchmarks/bench_planner.py [--n 200] [--hand pisa_iit_softhand] [--baseline 3447c98]
     [--mesh-vertices 82 1522 9802 39602]
IK success over random reachable poses: .venv/bin/python benchmarks/bench_ur5.py
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from baseline_tree import export_revision, tree_env

PARTS = ("strategy", "ik", "collision")


def pct(values: list[float], q: float) -> float:
    """The ``q`` quantile of ``values`` (nearest rank)."""
    s = sorted(values)
    return s[min(len(s) - 1, round(q * (len(s) - 1)))]


def uv_ellipsoid(n_vertices: int, radii: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """A closed UV-sphere mesh scaled to ``radii`` [m]: ``s - 2`` rings of ``s`` vertices and two poles, with
    ``(s - 2) s + 2`` close to ``n_vertices``; returns (vertices ``(N, 3)``, faces ``(M, 3)``)."""
    s = max(4, round(1.0 + math.sqrt(max(n_vertices - 1, 1))))
    rings = s - 2
    theta = np.linspace(0.0, math.pi, rings + 2)[1:-1]
    phi = np.linspace(0.0, 2.0 * math.pi, s, endpoint=False)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    ring_pts = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1).reshape(-1, 3)
    V = np.vstack([[0.0, 0.0, 1.0], ring_pts, [0.0, 0.0, -1.0]]) * np.asarray(radii)
    top, bottom = 0, len(V) - 1
    faces: list[tuple[int, int, int]] = []

    def idx(r: int, k: int) -> int:
        return 1 + r * s + k % s

    for k in range(s):
        faces.append((top, idx(0, k), idx(0, k + 1)))
        faces.append((bottom, idx(rings - 1, k + 1), idx(rings - 1, k)))
        for r in range(rings - 1):
            faces.append((idx(r, k), idx(r + 1, k), idx(r + 1, k + 1)))
            faces.append((idx(r, k), idx(r + 1, k + 1), idx(r, k + 1)))
    return V, np.asarray(faces, dtype=np.int64)


def _poses(rng: np.random.Generator, n: int) -> list[tuple[float, float, float]]:
    return [(rng.uniform(0.35, 0.6), rng.uniform(-0.25, 0.25), rng.uniform(-np.pi, np.pi)) for _ in range(n)]


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Time the plans of every cell in this process; returns timings [ms] and the plans' joints."""
    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()
    from softsig_service.objects import BUILTIN_NAMES, builtin_object, mesh
    from softsig_service.planning import Planner, PlanRequest, planning_model

    planner = Planner()
    planning_model(args.hand)
    rng = np.random.default_rng(args.seed)

    def run(obj: Any, strategy: str, cell: dict[str, Any]) -> None:
        req = PlanRequest(hand=args.hand, obj=obj, strategy=strategy)  # type: ignore[arg-type]
        c0, t0 = time.thread_time(), time.perf_counter()
        plan = planner.plan(req)
        cell["total"].append((time.perf_counter() - t0) * 1e3)
        cell["cpu"].append((time.thread_time() - c0) * 1e3)
        for part in PARTS:
            cell[part].append(plan.timing[part] * 1e3)
        cell["ok"] += int(plan.success)
        cell["q"].append(plan.joint_positions)
        cell["q_pre"].append(plan.pre_grasp_joint_positions)

    def new_cell() -> dict[str, Any]:
        return {"total": [], "cpu": [], "ok": 0, "q": [], "q_pre": [], **{p: [] for p in PARTS}}

    out: dict[str, Any] = {"cells": {}, "mesh": {}}
    for strategy in ("S", "C"):
        for name in BUILTIN_NAMES:
            cell = out["cells"][f"{strategy} {name}"] = new_cell()
            for x, y, yaw in _poses(rng, args.n):
                run(builtin_object(name, x=x, y=y, yaw=yaw), strategy, cell)
    for n_vertices in args.mesh_vertices:
        V, F = uv_ellipsoid(n_vertices, (0.05, 0.035, 0.035))
        poses = _poses(np.random.default_rng(args.seed + n_vertices), args.mesh_n)
        row: dict[str, Any] = {"vertices": len(V)}
        t0 = time.perf_counter()
        obj = mesh(V, F, 0.2, x=poses[0][0], y=poses[0][1], yaw=poses[0][2])
        cold = new_cell()
        run(obj, "S", cold)
        row["cold"] = (time.perf_counter() - t0) * 1e3  # object construction + first plan
        for strategy in ("S", "C"):
            cell, box = new_cell(), new_cell()
            for x, y, yaw in poses:
                run(obj.with_pose(x, y, yaw), strategy, cell)
                run(builtin_object("box", x=x, y=y, yaw=yaw), strategy, box)
            row[strategy] = cell
            row[f"{strategy} box"] = box
        out["mesh"][str(n_vertices)] = row
    return out


def _child(args: argparse.Namespace, package_root: Path | None, path: Path) -> dict[str, Any]:
    """Run :func:`measure` in a new process, against the package under ``package_root`` (None: this tree)."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--emit", str(path), "--n", str(args.n),
           "--hand", args.hand, "--seed", str(args.seed), "--mesh-n", str(args.mesh_n),
           "--mesh-vertices", *map(str, args.mesh_vertices)]  # fmt: skip
    env, cwd = tree_env(package_root)
    subprocess.run(cmd, check=True, env=env, cwd=cwd)
    with path.open() as f:
        data: dict[str, Any] = json.load(f)
    return data


def _merge(into: dict[str, Any] | None, new: dict[str, Any]) -> dict[str, Any]:
    """Append the lists of ``new`` to those of ``into`` (rounds of the same cells)."""
    if into is None:
        return new
    for key, cell in new["cells"].items():
        for k, v in cell.items():
            into["cells"][key][k] += v
    for key, row in new["mesh"].items():
        for k, v in row.items():
            if isinstance(v, dict):
                for kk, vv in v.items():
                    into["mesh"][key][k][kk] += vv
            elif k == "cold":
                into["mesh"][key].setdefault("colds", [into["mesh"][key]["cold"]]).append(v)
    return into


def _row(cell: dict[str, Any]) -> str:
    med = [statistics.median(cell[p]) for p in PARTS]
    return (f"{cell['ok']:5d} {pct(cell['total'], 0.5):7.2f} {pct(cell['total'], 0.95):7.2f} "
            f"{pct(cell['cpu'], 0.5):6.2f} {med[0]:6.2f} {med[1]:5.2f} {med[2]:5.2f}")  # fmt: skip


def _max_joint_difference(a: list[Any], b: list[Any]) -> tuple[float, int]:
    """Largest |q_a - q_b| [rad] over plans both found, and how many plans differ in success."""
    worst, differ = 0.0, 0
    for qa, qb in zip(a, b, strict=True):
        if (qa is None) != (qb is None):
            differ += 1
        elif qa is not None:
            worst = max(worst, float(np.max(np.abs(np.asarray(qa) - np.asarray(qb)))))
    return worst, differ


def report(args: argparse.Namespace, after: dict[str, Any], before: dict[str, Any] | None) -> None:
    """Print the tables: per cell (and per mesh size) the figures after, and before when given."""
    head = "   ok     p50     p95    cpu  strat    IK  coll."
    print(f"hand {args.hand}, {args.n} plans per cell; times [ms], p50/p95 wall, cpu = median thread CPU time, "
          "strat/IK/coll. = medians of the plan's own split")  # fmt: skip
    if before is not None:
        print(f"{'':17s} | before ({args.baseline}){' ' * (len(head) - 10 - len(args.baseline))}| after")
        print(f"{'strategy object':17s} |{head} |{head} | p50 ratio | max |dq| grasp, pre-grasp [rad]")
    else:
        print(f"{'strategy object':17s} |{head}")
    for key, cell in after["cells"].items():
        line = f"{key:17s} |"
        if before is not None:
            b = before["cells"][key]
            dq, differ = _max_joint_difference(b["q"], cell["q"])
            dqp, differ_pre = _max_joint_difference(b["q_pre"], cell["q_pre"])
            ratio = pct(b["total"], 0.5) / pct(cell["total"], 0.5)
            line += f"{_row(b)} |{_row(cell)} | {ratio:8.1f}x | {dq:.1e}, {dqp:.1e}"
            if differ or differ_pre:
                line += f" ({differ + differ_pre} plans differ in success)"
        else:
            line += _row(cell)
        print(line)
    if not after["mesh"]:
        return
    print("\nmesh object (ellipsoid 50 x 35 x 35 mm), plans at random poses; cold = construction + first plan")
    for label, data in (("before", before), ("after", after)):
        if data is None:
            continue
        print(f"{label}: {'vertices':>8s} {'cold':>8s} | {'S p50':>7s} {'S p95':>7s} {'box p50':>7s} {'ratio':>5s} "
              f"| {'C p50':>7s} {'C p95':>7s} {'box p50':>7s} {'ratio':>5s}")  # fmt: skip
        for row in data["mesh"].values():
            cold = statistics.median(row.get("colds", [row["cold"]]))
            line = f"{'':7s} {row['vertices']:8d} {cold:8.1f}"
            for s in ("S", "C"):
                p50, box = pct(row[s]["total"], 0.5), pct(row[f"{s} box"]["total"], 0.5)
                line += f" | {p50:7.2f} {pct(row[s]['total'], 0.95):7.2f} {box:7.2f} {p50 / box:5.2f}"
            print(line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=200, help="plans per (strategy, object)")
    parser.add_argument("--hand", default="pisa_iit_softhand")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--baseline", metavar="REV", help="also run the package at this git revision")
    parser.add_argument("--rounds", type=int, default=1, help="with --baseline: alternate runs per side")
    parser.add_argument("--mesh-vertices", type=int, nargs="*", default=[], metavar="N")
    parser.add_argument("--mesh-n", type=int, default=20, help="plans per strategy and mesh size")
    parser.add_argument("--emit", type=Path, help=argparse.SUPPRESS)  # child mode: write the raw figures
    args = parser.parse_args()
    if args.emit is not None:
        args.emit.write_text(json.dumps(measure(args)))
        return
    if args.baseline is None:
        report(args, measure(args), None)
        return
    with tempfile.TemporaryDirectory(prefix="bench-baseline-") as tmp:
        base_root = export_revision(args.baseline, Path(tmp))
        before = after = None
        for r in range(args.rounds):
            before = _merge(before, _child(args, base_root, Path(tmp) / f"before{r}.json"))
            after = _merge(after, _child(args, None, Path(tmp) / f"after{r}.json"))
        assert before is not None and after is not None
        report(args, after, before)


if __name__ == "__main__":
    main()
