"""Monte Carlo validation campaigns: conditions x objects x strategies x trials, in parallel, resumable, reported.

A campaign (DESIGN §7, the paper's Table I) runs :func:`~softsig_service.simulation.rollout.run_trial` for every
cell (condition ``(sigma_r [rad], sigma_t [m])``, object, strategy) ``trials`` times:

* **Seeds**: trial ``k`` of cell ``(i, j, s)`` (condition, object and strategy indices) gets
  ``SeedSequence(entropy=seed, spawn_key=(i, j, s, k)).generate_state(1, uint32)[0]``: deterministic, independent
  between cells (S and C see independent perturbations, as Fisher's test assumes), echoed in every record.
* **Backends**: ``"local"``: a ``concurrent.futures.ProcessPoolExecutor`` with the ``spawn`` start method and
  ``workers`` processes (default: every core this process may use); each worker builds its planner and MuJoCo
  scenes once (module caches) and reuses them. ``"ray"``: tasks on a Ray cluster (``address`` of a running
  cluster, or a local one with ``workers`` CPUs); Ray is an optional extra, imported only then. Every node of
  a remote cluster needs softsig and its dependencies installed (tasks import ``softsig_service``). The
  main process writes the files in both cases.
* **Files** in ``out``: ``campaign.json`` (the spec), ``trials.jsonl`` (one JSON record per finished trial,
  appended and flushed as trials finish), and when every trial is done (or at :func:`write_report`):
  ``results.json`` (spec, records sorted by index, summary), ``results.csv``, ``report.md`` and ``table1.png``.
* **Resuming**: running the same spec with the same ``out`` skips every trial already in ``trials.jsonl`` (a
  torn last line of an interrupted run is ignored). A different spec in the same folder is refused.
* **Report**: a Markdown table laid out like the paper's Table I (rows objects, columns conditions, each cell
  "S / C" successes out of N) beside the paper's real-robot counts, Wilson 95 % intervals
  (``scipy.stats.binomtest(...).proportion_ci(method="wilson")``), Fisher's exact test of S vs C per cell,
  pooled per condition and overall (two-sided, and one-sided for the paper's claim C > S), the failure
  reasons, and a bar chart (matplotlib, Agg).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import os
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any, Literal

import numpy as np

from softsig_service.errors import Conflict, InvalidInput

Condition = tuple[float, float]
"""(sigma_r [rad], sigma_t [m])."""

TABLE1_CONDITIONS: tuple[Condition, ...] = ((0.0, 0.0), (0.1, 0.01), (0.2, 0.02))
"""The paper's three uncertainty levels (DESIGN §7)."""
TABLE1_OBJECTS: tuple[str, ...] = ("box", "apple", "cylinder")
STRATEGY_NAMES: tuple[str, ...] = ("S", "C")
PAPER_TABLE1: dict[str, tuple[tuple[int, int], ...]] = {
    "box": ((17, 20), (15, 16), (3, 11)),
    "apple": ((20, 20), (19, 19), (17, 15)),
    "cylinder": ((18, 19), (10, 16), (8, 11)),
}
"""The paper's real-robot successes (S, C) out of :data:`PAPER_TRIALS` per condition of
:data:`TABLE1_CONDITIONS` (DESIGN §7)."""
PAPER_TRIALS = 20
BACKENDS: tuple[str, ...] = ("local", "ray")

SPEC_FILE = "campaign.json"
TRIALS_FILE = "trials.jsonl"
RESULTS_JSON = "results.json"
RESULTS_CSV = "results.csv"
REPORT_MD = "report.md"
CHART_PNG = "table1.png"


# ----------------------------------------------------------------------------------------------------------
# the grid
# ----------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TrialSpec:
    """One trial of a campaign: its cell, its index in the cell and its derived seed."""

    index: int
    condition: int
    sigma_r: float
    sigma_t: float
    object: str
    strategy: str
    trial: int
    seed: int
    hand: str
    x: float
    y: float
    yaw: float
    cs_method: str = "ellipsoid"
    criterion: str = "absolute"
    placement: str = "open_centre"

    @property
    def key(self) -> str:
        """A stable identifier: ``c<condition>/<object>/<strategy>/<trial>``."""
        return f"c{self.condition}/{self.object}/{self.strategy}/{self.trial}"


def trial_seed(seed: int, cell: Sequence[int], trial: int) -> int:
    """The seed of trial ``trial`` of the cell with indices ``cell``: ``SeedSequence(seed, spawn_key=(*cell,
    trial))``'s first 32-bit word (deterministic; distinct streams for distinct keys)."""
    ss = np.random.SeedSequence(entropy=seed, spawn_key=(*cell, trial))
    return int(ss.generate_state(1, dtype=np.uint32)[0])


@dataclass(frozen=True)
class CampaignSpec:
    """A campaign grid. ``objects`` are built-in names (DESIGN §7) placed at ``(x, y, yaw)`` [m, m, rad].

    ``cs_method`` ("ellipsoid" | "pca" | "mesh"), ``criterion`` (the ellipsoid CS's "absolute" | "relative") and
    ``placement`` ("open_centre" | "grasp_centre" | "previous") are passed to every plan (see :class:`PlanRequest`)."""

    hand: str = "pisa_iit_softhand"
    conditions: tuple[Condition, ...] = TABLE1_CONDITIONS
    objects: tuple[str, ...] = TABLE1_OBJECTS
    strategies: tuple[str, ...] = STRATEGY_NAMES
    trials: int = 20
    seed: int = 0
    x: float = 0.5
    y: float = 0.0
    yaw: float = 0.0
    cs_method: str = "ellipsoid"
    criterion: str = "absolute"
    placement: str = "open_centre"

    def __post_init__(self) -> None:
        from softsig_service.planning.objects import BUILTIN_NAMES
        from softsig_service.planning.planner import PLACEMENTS
        from softsig_service.signatures.closure import CRITERIA, METHODS

        for name, value, choices in (("cs_method", self.cs_method, METHODS), ("criterion", self.criterion, CRITERIA),
                                     ("placement", self.placement, PLACEMENTS)):  # fmt: skip
            if value not in choices:
                raise InvalidInput(f"unknown {name}", field=name, value=value, choices=tuple(choices))

        if self.trials < 1:
            raise InvalidInput("need at least one trial per cell", field="trials", value=self.trials)
        if self.seed < 0:
            raise InvalidInput("seed must be >= 0", field="seed", value=self.seed)
        if not self.conditions or not self.objects or not self.strategies:
            raise InvalidInput("the grid is empty", field="conditions")
        for k, cond in enumerate(self.conditions):
            if len(cond) != 2 or not all(math.isfinite(v) and v >= 0.0 for v in cond):
                raise InvalidInput(
                    "a condition is (sigma_r >= 0 [rad], sigma_t >= 0 [m])", field=f"conditions[{k}]", value=cond
                )
        for name in self.objects:
            if name not in BUILTIN_NAMES:
                raise InvalidInput("unknown object", field="objects", value=name, choices=BUILTIN_NAMES)
        for s in self.strategies:
            if s not in STRATEGY_NAMES:
                raise InvalidInput("unknown strategy", field="strategies", value=s, choices=STRATEGY_NAMES)

    def trial_specs(self) -> list[TrialSpec]:
        """Every trial, in the order condition, object, strategy, trial."""
        out: list[TrialSpec] = []
        for i, (sr, st) in enumerate(self.conditions):
            for j, obj in enumerate(self.objects):
                for s, strat in enumerate(self.strategies):
                    for k in range(self.trials):
                        out.append(
                            TrialSpec(
                                index=len(out),
                                condition=i,
                                sigma_r=float(sr),
                                sigma_t=float(st),
                                object=obj,
                                strategy=strat,
                                trial=k,
                                seed=trial_seed(self.seed, (i, j, s), k),
                                hand=self.hand,
                                x=self.x,
                                y=self.y,
                                yaw=self.yaw,
                                cs_method=self.cs_method,
                                criterion=self.criterion,
                                placement=self.placement,
                            )
                        )
        return out

    def to_json_dict(self) -> dict[str, Any]:
        """The spec as JSON (conditions as ``[sigma_r, sigma_t]`` pairs)."""
        d = dataclasses.asdict(self)
        d["conditions"] = [list(c) for c in self.conditions]
        d["objects"] = list(self.objects)
        d["strategies"] = list(self.strategies)
        return d

    @staticmethod
    def from_json_dict(d: Mapping[str, Any]) -> CampaignSpec:
        """Inverse of :meth:`to_json_dict`."""
        return CampaignSpec(
            hand=str(d["hand"]),
            conditions=tuple((float(a), float(b)) for a, b in d["conditions"]),
            objects=tuple(d["objects"]),
            strategies=tuple(d["strategies"]),
            trials=int(d["trials"]),
            seed=int(d["seed"]),
            x=float(d["x"]),
            y=float(d["y"]),
            yaw=float(d["yaw"]),
            cs_method=str(d.get("cs_method", "ellipsoid")),
            criterion=str(d.get("criterion", "absolute")),
            placement=str(d.get("placement", "previous")),
        )


# ----------------------------------------------------------------------------------------------------------
# running one trial (in a worker)
# ----------------------------------------------------------------------------------------------------------


def run_trial_spec(spec: TrialSpec) -> dict[str, Any]:
    """Run one campaign trial and return its JSON record (used by the worker processes and Ray tasks)."""
    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()
    from softsig_service.planning.objects import builtin_object
    from softsig_service.simulation.rollout import run_trial

    obj = builtin_object(spec.object, x=spec.x, y=spec.y, yaw=spec.yaw)
    result = run_trial(
        spec.hand,
        obj,
        spec.strategy,  # type: ignore[arg-type]
        seed=spec.seed,
        sigma_r=spec.sigma_r,
        sigma_t=spec.sigma_t,
        plan_options={"cs_method": spec.cs_method, "cs_criterion": spec.criterion, "placement": spec.placement},
    )
    record = result.to_json_dict()
    record.update(key=spec.key, index=spec.index, condition=spec.condition, trial=spec.trial, pid=os.getpid())
    return record


def _worker_init() -> None:
    """Worker start-up: choose MuJoCo's GL backend before MuJoCo is imported."""
    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()


# ----------------------------------------------------------------------------------------------------------
# the record file
# ----------------------------------------------------------------------------------------------------------


def read_records(path: Path) -> list[dict[str, Any]]:
    """The records of a ``trials.jsonl`` (a torn or malformed line, e.g. the last of a killed run, is skipped)."""
    if not path.is_file():
        return []
    out: list[dict[str, Any]] = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(rec, dict) and "key" in rec:
            out.append(rec)
    return out


def _ends_torn(path: Path) -> bool:
    """Whether the file is non-empty and does not end with a newline."""
    size = path.stat().st_size
    if size == 0:
        return False
    with path.open("rb") as f:
        f.seek(size - 1)
        return f.read(1) != b"\n"


def _check_out_dir(out: Path, spec: CampaignSpec) -> None:
    out.mkdir(parents=True, exist_ok=True)
    path = out / SPEC_FILE
    if path.is_file():
        try:
            old = json.loads(path.read_text(encoding="utf-8"))
        except json.JSONDecodeError:
            old = None
        if old != spec.to_json_dict():
            raise Conflict(
                "the output folder holds a different campaign; use another --out or the same parameters",
                field="out",
                value=str(out),
            )
    else:
        path.write_text(json.dumps(spec.to_json_dict(), indent=2) + "\n", encoding="utf-8")


# ----------------------------------------------------------------------------------------------------------
# running a campaign
# ----------------------------------------------------------------------------------------------------------


@dataclass
class CampaignResult:
    """What :func:`run_campaign` did: the spec, every record so far (sorted by index), how many trials it ran
    now and how many it skipped as already done, whether the grid is complete, wall time [s], the files."""

    spec: CampaignSpec
    records: list[dict[str, Any]]
    ran: int
    skipped: int
    complete: bool
    wall_time: float
    files: dict[str, str] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)


ProgressCallback = Callable[[int, int], None]
"""Called with (done, total) after each finished trial."""


def default_workers() -> int:
    """Every core this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def run_campaign(
    spec: CampaignSpec,
    out: Path,
    *,
    workers: int | None = None,
    backend: Literal["local", "ray"] = "local",
    address: str | None = None,
    progress: bool | ProgressCallback = False,
    max_trials: int | None = None,
) -> CampaignResult:
    """Run (or resume) ``spec`` writing into ``out``; see the module docstring.

    ``workers``: processes (local) or CPUs of a local Ray; default :func:`default_workers`. ``workers=1`` with
    the local backend runs in this process (no pool). ``progress``: True for a rich progress bar on stderr, or
    a callback. ``max_trials``: stop after this many new trials (an interruption on purpose; the campaign
    stays resumable). Raises :class:`InvalidInput` for a bad backend or worker count or a missing Ray,
    :class:`Conflict` if ``out`` holds another campaign.
    """
    if backend not in BACKENDS:
        raise InvalidInput("unknown backend", field="backend", value=backend, choices=BACKENDS)
    n_workers = default_workers() if workers is None else workers
    if n_workers < 1:
        raise InvalidInput("need at least one worker", field="workers", value=workers)
    if max_trials is not None and max_trials < 0:
        raise InvalidInput("must be >= 0", field="max_trials", value=max_trials)
    t0 = time.perf_counter()
    out = Path(out)
    _check_out_dir(out, spec)
    trials_path = out / TRIALS_FILE
    specs = spec.trial_specs()
    by_key = {t.key: t for t in specs}
    done = {r["key"]: r for r in read_records(trials_path) if r["key"] in by_key}
    todo = [t for t in specs if t.key not in done]
    skipped = len(specs) - len(todo)
    if max_trials is not None:
        todo = todo[:max_trials]

    callback = progress if callable(progress) else None
    ran = 0
    with (
        _progress_bar(bool(progress) and callback is None, len(specs), skipped) as bar_update,
        trials_path.open("a", encoding="utf-8") as sink,
    ):
        if todo and _ends_torn(trials_path):
            sink.write("\n")  # a torn last line of an interrupted run stays alone on its line
        for record in _execute(todo, backend, n_workers, address):
            sink.write(json.dumps(record) + "\n")
            sink.flush()
            done[record["key"]] = record
            ran += 1
            bar_update()
            if callback is not None:
                callback(len(done), len(specs))

    records = sorted(done.values(), key=lambda r: int(r["index"]))
    complete = len(records) == len(specs)
    result = CampaignResult(
        spec=spec, records=records, ran=ran, skipped=skipped, complete=complete, wall_time=time.perf_counter() - t0
    )
    if complete:
        result.files = write_report(spec, records, out, wall_time=result.wall_time)
        result.summary = summarize(spec, records)
    return result


@contextmanager
def _progress_bar(enabled: bool, total: int, completed: int) -> Iterator[Callable[[], None]]:
    """A rich progress bar on stderr (or nothing); yields the function that advances it by one trial."""
    if not enabled:
        yield lambda: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    bar = Progress(
        TextColumn("trials"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(), console=Console(stderr=True)
    )
    task = bar.add_task("trials", total=total, completed=completed)
    with bar:
        yield lambda: bar.advance(task)


def _execute(todo: list[TrialSpec], backend: str, workers: int, address: str | None) -> Iterator[dict[str, Any]]:
    if not todo:
        return
    if backend == "ray":
        yield from _execute_ray(todo, workers, address)
    elif workers == 1:
        _worker_init()
        for t in todo:
            yield run_trial_spec(t)
    else:
        yield from _execute_pool(todo, workers)


def _execute_pool(todo: list[TrialSpec], workers: int) -> Iterator[dict[str, Any]]:
    """A spawn-context process pool; at most ``2 * workers`` trials in flight (an interrupt loses little)."""
    ctx = get_context("spawn")
    pending: set[Future[dict[str, Any]]] = set()
    queue = iter(todo)
    with ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=ctx, initializer=_worker_init) as pool:
        try:
            for t in queue:
                pending.add(pool.submit(run_trial_spec, t))
                if len(pending) >= 2 * workers:
                    break
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    yield f.result()
                    nxt = next(queue, None)
                    if nxt is not None:
                        pending.add(pool.submit(run_trial_spec, nxt))
        finally:
            for f in pending:
                f.cancel()


def _execute_ray(todo: list[TrialSpec], workers: int, address: str | None) -> Iterator[dict[str, Any]]:
    try:
        import ray
    except ImportError:
        raise InvalidInput(
            "the Ray backend needs the 'ray' package: pip install 'softsig[ray]' (or pip install ray)",
            field="backend",
            value="ray",
        ) from None
    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=2)(run_trial_spec)
        pending = [remote.remote(t) for t in todo]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            for ref in ready:
                yield ray.get(ref)
    finally:
        if started:
            ray.shutdown()


# ----------------------------------------------------------------------------------------------------------
# statistics and the report
# ----------------------------------------------------------------------------------------------------------


def wilson_interval(successes: int, n: int) -> tuple[float, float]:
    """Wilson score 95 % interval of a success rate (``scipy.stats.binomtest(...).proportion_ci``)."""
    from scipy.stats import binomtest

    if n == 0:
        return (0.0, 1.0)
    ci = binomtest(successes, n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)


def fisher_p(s_succ: int, s_n: int, c_succ: int, c_n: int) -> dict[str, float]:
    """Fisher's exact test of S vs C on the 2x2 table [[S succ, S fail], [C succ, C fail]]:
    ``two_sided`` and ``c_greater`` (one-sided, alternative: C's success rate is higher)."""
    from scipy.stats import fisher_exact

    table = [[s_succ, s_n - s_succ], [c_succ, c_n - c_succ]]
    two = fisher_exact(table, alternative="two-sided").pvalue
    less = fisher_exact(table, alternative="less").pvalue  # odds(S) < odds(C)
    return {"two_sided": float(two), "c_greater": float(less)}


def _counts(records: Iterable[Mapping[str, Any]]) -> dict[tuple[int, str, str], tuple[int, int]]:
    out: dict[tuple[int, str, str], list[int]] = {}
    for r in records:
        k = (int(r["condition"]), str(r["object"]), str(r["strategy"]))
        c = out.setdefault(k, [0, 0])
        c[0] += bool(r["success"])
        c[1] += 1
    return {k: (v[0], v[1]) for k, v in out.items()}


def summarize(spec: CampaignSpec, records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Counts, Wilson intervals and Fisher p-values per cell, pooled per condition and overall, the failure
    reasons per cell, and the paper's counts where the grid matches Table I."""
    counts = _counts(records)
    cells: list[dict[str, Any]] = []

    def stats(pairs: dict[str, tuple[int, int]]) -> dict[str, Any]:
        d: dict[str, Any] = {}
        for s, (k, n) in pairs.items():
            d[s] = {"successes": k, "trials": n, "rate": k / n if n else None, "wilson95": wilson_interval(k, n)}
        if "S" in pairs and "C" in pairs:
            d["fisher"] = fisher_p(*pairs["S"], *pairs["C"])
        return d

    paper = _paper_counts(spec)
    for i, cond in enumerate(spec.conditions):
        for obj in spec.objects:
            pairs = {s: counts.get((i, obj, s), (0, 0)) for s in spec.strategies}
            reasons = {
                s: dict(
                    Counter(
                        str(r["reason"])
                        for r in records
                        if int(r["condition"]) == i and r["object"] == obj and r["strategy"] == s and not r["success"]
                    )
                )
                for s in spec.strategies
            }
            cell = {
                "condition": i,
                "sigma_r": cond[0],
                "sigma_t": cond[1],
                "object": obj,
                **stats(pairs),
                "reasons": reasons,
            }
            if paper is not None and obj in PAPER_TABLE1:
                ps, pc = PAPER_TABLE1[obj][i]
                cell["paper"] = {
                    "S": ps,
                    "C": pc,
                    "trials": PAPER_TRIALS,
                    "fisher": fisher_p(ps, PAPER_TRIALS, pc, PAPER_TRIALS),
                }
            cells.append(cell)
    pooled: list[dict[str, Any]] = []
    for i, cond in enumerate(spec.conditions):
        pairs = {s: _sum(counts.get((i, o, s), (0, 0)) for o in spec.objects) for s in spec.strategies}
        pooled.append({"condition": i, "sigma_r": cond[0], "sigma_t": cond[1], **stats(pairs)})
    overall = stats({s: _sum(v for k, v in counts.items() if k[2] == s) for s in spec.strategies})
    return {"cells": cells, "pooled_per_condition": pooled, "pooled": overall, "paper_available": paper is not None}


def _sum(pairs: Iterable[tuple[int, int]]) -> tuple[int, int]:
    k = n = 0
    for a, b in pairs:
        k, n = k + a, n + b
    return k, n


def _paper_counts(spec: CampaignSpec) -> dict[str, tuple[tuple[int, int], ...]] | None:
    """The paper's counts if the conditions are Table I's."""
    if tuple(spec.conditions) != TABLE1_CONDITIONS:
        return None
    return PAPER_TABLE1


def _cond_label(cond: Condition) -> str:
    return f"σr={cond[0]:g} rad, σt={cond[1]:g} m"


def _ci(d: Mapping[str, Any]) -> str:
    lo, hi = d["wilson95"]
    return f"{d['successes']}/{d['trials']} [{lo:.2f}, {hi:.2f}]"


def report_markdown(spec: CampaignSpec, summary: Mapping[str, Any], wall_time: float | None = None) -> str:
    """The Markdown report: Table I layout (ours and the paper's), intervals, p-values, failure reasons."""
    lines = [f"# Validation campaign: {spec.hand}", ""]
    lines.append(
        f"{spec.trials} trials per cell, campaign seed {spec.seed}, objects at x = {spec.x} m, "
        f"y = {spec.y} m, yaw = {spec.yaw} rad (nominal). Closure signature: {spec.cs_method} method"
        f"{', ' + spec.criterion + ' criterion' if spec.cs_method == 'ellipsoid' else ''}; placement: "
        f"{spec.placement}."
    )
    if wall_time is not None:
        lines.append(f"Wall time of the last run: {wall_time:.1f} s.")
    lines += ["", "## Successes, S / C (out of N per cell)", ""]
    header = "| object | " + " | ".join(_cond_label(c) for c in spec.conditions) + " |"
    lines += [header, "|---" * (len(spec.conditions) + 1) + "|"]
    cells = {(c["condition"], c["object"]): c for c in summary["cells"]}
    for obj in spec.objects:
        row = [obj]
        for i in range(len(spec.conditions)):
            c = cells[(i, obj)]
            row.append(" / ".join(str(c[s]["successes"]) for s in spec.strategies) + f" (N={spec.trials})")
        lines.append("| " + " | ".join(row) + " |")
    if summary.get("paper_available"):
        lines += [
            "",
            "## The paper's real-robot counts, S / C (out of 20)",
            "",
            header,
            "|---" * (len(spec.conditions) + 1) + "|",
        ]
        for obj in spec.objects:
            if obj in PAPER_TABLE1:
                lines.append("| " + obj + " | " + " | ".join(f"{s} / {c}" for s, c in PAPER_TABLE1[obj]) + " |")
    if set(spec.strategies) == {"S", "C"}:
        lines += [
            "",
            "## Per cell: Wilson 95 % intervals and Fisher's exact test (S vs C)",
            "",
            "| condition | object | S (succ/N [95 % CI]) | C (succ/N [95 % CI]) | p two-sided | p (C > S) "
            "| paper p two-sided | paper p (C > S) |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for c in summary["cells"]:
            pp = c.get("paper", {}).get("fisher")
            paper_cols = f"{pp['two_sided']:.3g} | {pp['c_greater']:.3g}" if pp else "– | –"
            lines.append(
                f"| {_cond_label(spec.conditions[c['condition']])} | {c['object']} | {_ci(c['S'])} | "
                f"{_ci(c['C'])} | {c['fisher']['two_sided']:.3g} | {c['fisher']['c_greater']:.3g} | "
                f"{paper_cols} |"
            )
        lines += [
            "",
            "## Pooled over objects",
            "",
            "| condition | S | C | p two-sided | p (C > S) |",
            "|---|---|---|---|---|",
        ]
        for p in summary["pooled_per_condition"]:
            lines.append(
                f"| {_cond_label(spec.conditions[p['condition']])} | {_ci(p['S'])} | {_ci(p['C'])} | "
                f"{p['fisher']['two_sided']:.3g} | {p['fisher']['c_greater']:.3g} |"
            )
        o = summary["pooled"]
        lines.append(
            f"| all | {_ci(o['S'])} | {_ci(o['C'])} | {o['fisher']['two_sided']:.3g} | {o['fisher']['c_greater']:.3g} |"
        )
    lines += ["", "## Failure reasons", "", "| condition | object | strategy | reasons |", "|---|---|---|---|"]
    for c in summary["cells"]:
        for s in spec.strategies:
            rs = ", ".join(f"{k} {v}" for k, v in sorted(c["reasons"][s].items())) or "–"
            lines.append(f"| {_cond_label(spec.conditions[c['condition']])} | {c['object']} | {s} | {rs} |")
    lines += ["", f"Chart: `{CHART_PNG}`.", ""]
    return "\n".join(lines)


def plot_summary(spec: CampaignSpec, summary: Mapping[str, Any], path: Path) -> None:
    """Bar chart of the success rates per object and condition, S and C, with Wilson 95 % error bars, and the
    paper's rates as markers (matplotlib ``Figure``, Agg; PNG/PDF/SVG by suffix)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    cells = {(c["condition"], c["object"]): c for c in summary["cells"]}
    fig = Figure(figsize=(3.2 * len(spec.objects) + 1.0, 3.6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(spec.objects), sharey=True, squeeze=False)[0]
    colors = {"S": "#9e9e9e", "C": "#d95f02"}
    width = 0.8 / len(spec.strategies)
    x = np.arange(len(spec.conditions))
    for ax, obj in zip(axes, spec.objects, strict=True):
        for k, s in enumerate(spec.strategies):
            rates, lo, hi, paper = [], [], [], []
            for i in range(len(spec.conditions)):
                d = cells[(i, obj)][s]
                r = d["rate"] or 0.0
                rates.append(r)
                lo.append(r - d["wilson95"][0])
                hi.append(d["wilson95"][1] - r)
                p = cells[(i, obj)].get("paper")
                paper.append(p[s] / p["trials"] if p else np.nan)
            pos = x - 0.4 + width * (k + 0.5)
            ax.bar(pos, rates, width, color=colors.get(s), label=f"{s} (sim)", yerr=[lo, hi], capsize=3)
            ax.plot(pos, paper, "k^" if s == "S" else "kv", markersize=6, label=f"{s} (paper)")
        ax.set_title(obj)
        ax.set_xticks(x)
        ax.set_xticklabels([f"{c[0]:g} rad\n{c[1]:g} m" for c in spec.conditions], fontsize=8)
        ax.set_ylim(0.0, 1.05)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel("success rate")
    axes[-1].legend(fontsize=7, loc="lower left")
    fig.suptitle(f"{spec.hand}: S vs C under pose uncertainty ({spec.trials} trials per bar, Wilson 95 %)", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


CSV_COLUMNS: tuple[str, ...] = (
    "index",
    "key",
    "condition",
    "sigma_r",
    "sigma_t",
    "object",
    "strategy",
    "trial",
    "seed",
    "success",
    "reason",
    "lift_height",
    "max_lift",
    "touching_after_close",
    "touching_end",
    "touching_table_end",
    "sag",
    "slip",
    "d_yaw",
    "dx",
    "dy",
    "plan_reasons",
    "arm_collision_time",
    "sim_time",
    "wall_time",
)


def records_csv(records: Sequence[Mapping[str, Any]]) -> str:
    """The records as CSV (one row per trial; units m, rad, s)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in records:
        p = r.get("perturbation", {})
        row = {
            **r,
            "d_yaw": p.get("d_yaw"),
            "dx": p.get("dx"),
            "dy": p.get("dy"),
            "plan_reasons": ";".join(r.get("plan_reasons", [])),
        }
        w.writerow(["" if row.get(c) is None else row.get(c) for c in CSV_COLUMNS])
    return buf.getvalue()


def write_report(
    spec: CampaignSpec, records: Sequence[Mapping[str, Any]], out: Path, wall_time: float | None = None
) -> dict[str, str]:
    """Write ``results.json``, ``results.csv``, ``report.md`` and ``table1.png`` into ``out``; their paths."""
    out.mkdir(parents=True, exist_ok=True)
    summary = summarize(spec, records)
    files = {
        "json": out / RESULTS_JSON,
        "csv": out / RESULTS_CSV,
        "report": out / REPORT_MD,
        "chart": out / CHART_PNG,
        "trials": out / TRIALS_FILE,
    }
    payload = {"campaign": spec.to_json_dict(), "summary": summary, "records": list(records)}
    files["json"].write_text(json.dumps(payload, indent=1) + "\n", encoding="utf-8")
    files["csv"].write_text(records_csv(records), encoding="utf-8")
    files["report"].write_text(report_markdown(spec, summary, wall_time), encoding="utf-8")
    plot_summary(spec, summary, files["chart"])
    return {k: str(v) for k, v in files.items()}
