"""Monte Carlo validation campaigns: conditions x objects x strategies x trials, in parallel, resumable, reported.

A campaign (docs/design.md §7, the paper's Table I) runs :func:`~softsig_service.experiments.trial.run_trial` for every
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
* **Strategy R** (:mod:`softsig_service.planning.strategy_r`): before the trials, the hand's capture model on
  each object is read from ``capture/<object>.json`` or built there by simulation
  (:mod:`softsig_service.experiments.capture`); R's trials plan with it for their condition's sigmas.
* **Replicas**: trials that are the same simulation (a cell with sigmas 0 draws the zero perturbation for every
  seed) are simulated once and recorded for each, with ``same_as`` naming the simulated one
  (:mod:`softsig_service.experiments.replicas`; ``reuse_identical=False`` simulates all).
* **Resuming**: running the same spec with the same ``out`` skips every trial already in ``trials.jsonl`` (a
  torn last line of an interrupted run is ignored). A different spec in the same folder is refused.
* **Report** (:mod:`softsig_service.experiments.report`): a Markdown table laid out like the paper's Table I
  (rows objects, columns conditions, each cell
  "S / C" successes out of N) beside the paper's real-robot counts, Wilson 95 % intervals
  (``scipy.stats.binomtest(...).proportion_ci(method="wilson")``), Fisher's exact test of S vs C per cell,
  pooled per condition and overall (two-sided, and one-sided for the paper's claim C > S), with R: R against the
  better of S and C the same way (one-sided: R better), the failure reasons, and a bar chart (matplotlib, Agg).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import time
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any, Literal

from softsig_service.config import Settings
from softsig_service.errors import Conflict, InvalidInput
from softsig_service.experiments.campaign_spec import (
    BACKENDS,
    CAPTURE_DIR,
    SPEC_FILE,
    TRIALS_FILE,
    CampaignSpec,
    TrialSpec,
    plan_options,
)
from softsig_service.experiments.replicas import group, replica
from softsig_service.experiments.report import write_report
from softsig_service.experiments.statistics import summarize
from softsig_service.signatures.capture import CaptureModel


def run_trial_spec(spec: TrialSpec, settings: Settings | None = None) -> dict[str, Any]:
    """Run one campaign trial under ``settings`` (model limits, robots folder; default: the built-in ones) and
    return its JSON record (used by the worker processes and Ray tasks)."""
    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()
    from softsig_service.experiments.trial import run_trial
    from softsig_service.objects import builtin_object

    obj = builtin_object(spec.object, x=spec.x, y=spec.y, yaw=spec.yaw)
    options = plan_options(spec)
    if spec.strategy == "R":
        options["capture"] = load_capture(spec.capture_file)
    result = run_trial(
        spec.hand,
        obj,
        spec.strategy,  # type: ignore[arg-type]
        seed=spec.seed,
        sigma_r=spec.sigma_r,
        sigma_t=spec.sigma_t,
        plan_options=options,
        settings=settings,
    )
    record = result.to_json_dict()
    record.update(key=spec.key, index=spec.index, condition=spec.condition, trial=spec.trial, pid=os.getpid())
    return record


@functools.lru_cache(maxsize=16)
def load_capture(path: str) -> CaptureModel:
    """The capture model stored at ``path`` (JSON of :meth:`CaptureModel.to_json_dict`), read once per process."""
    return CaptureModel.from_json_dict(json.loads(Path(path).read_text(encoding="utf-8")))


def ensure_capture_models(
    spec: CampaignSpec, out: Path, workers: int, settings: Settings | None = None
) -> dict[str, Path]:
    """For a campaign with strategy R: the capture model of the hand on each object, read from
    ``out/capture/<object>.json``, else copied there from the hand's shipped model when it was built for the same
    object pose, grid and plan options, else built now (:func:`~softsig_service.experiments.capture.
    build_capture_model` with its default grid, at the campaign's nominal pose and placement). Object -> file."""
    from softsig_service.experiments.capture import (
        CaptureGrid,
        build_capture_model,
        matching_shipped_capture,
        shipped_capture_path,
    )
    from softsig_service.objects import builtin_object

    folder = out / CAPTURE_DIR
    folder.mkdir(parents=True, exist_ok=True)
    options = plan_options(spec)
    files: dict[str, Path] = {}
    for name in spec.objects:
        path = folder / f"{name}.json"
        if not path.is_file():
            obj = builtin_object(name, x=spec.x, y=spec.y, yaw=spec.yaw).to_json()
            shipped = shipped_capture_path(spec.hand, name)
            text = matching_shipped_capture(shipped, obj, CaptureGrid(), options) if shipped is not None else None
            if text is None:
                text = json.dumps(
                    build_capture_model(
                        spec.hand, obj, workers=workers, plan_options=options, settings=settings
                    ).to_json_dict()
                )
            tmp = path.with_suffix(".tmp")
            tmp.write_text(text.rstrip("\n") + "\n", encoding="utf-8")
            os.replace(tmp, path)
        files[name] = path
    return files


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
    settings: Settings | None = None,
    reuse_identical: bool = True,
) -> CampaignResult:
    """Run (or resume) ``spec`` writing into ``out``; see the module docstring.

    ``workers``: processes (local) or CPUs of a local Ray; default :func:`default_workers`. ``workers=1`` with
    the local backend runs in this process (no pool). ``progress``: True for a rich progress bar on stderr, or
    a callback. ``max_trials``: stop after this many new trials (an interruption on purpose; the campaign
    stays resumable). ``settings``: the model limits and robots folder every trial loads under (default: the built-in
    ones; the service passes its own). ``reuse_identical``: simulate once the trials that are the same simulation
    (:mod:`softsig_service.experiments.replicas`; False simulates every trial). Raises :class:`InvalidInput` for
    a bad backend or worker count or a missing Ray, :class:`Conflict` if ``out`` holds another campaign.
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
    if "R" in spec.strategies:
        capture = ensure_capture_models(spec, out, n_workers if backend == "local" else 1, settings)
        specs = [dataclasses.replace(t, capture_file=str(capture[t.object])) if t.strategy == "R" else t for t in specs]
    by_key = {t.key: t for t in specs}
    done = {r["key"]: r for r in read_records(trials_path) if r["key"] in by_key}
    skipped = len(done)
    immediate, todo, followers = _plan_work(specs, done, reuse_identical)

    callback = progress if callable(progress) else None
    ran = 0
    with (
        _progress_bar(bool(progress) and callback is None, len(specs), skipped) as bar_update,
        trials_path.open("a", encoding="utf-8") as sink,
    ):
        if (immediate or todo) and _ends_torn(trials_path):
            sink.write("\n")  # a torn last line of an interrupted run stays alone on its line

        def outcomes() -> Iterator[dict[str, Any]]:
            yield from immediate
            for record in _execute(todo, backend, n_workers, address, settings):
                yield record
                yield from (replica(record, t) for t in followers.get(record["key"], ()))

        for record in outcomes():
            if max_trials is not None and ran >= max_trials:
                break
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


def _plan_work(
    specs: list[TrialSpec], done: dict[str, dict[str, Any]], reuse_identical: bool
) -> tuple[list[dict[str, Any]], list[TrialSpec], dict[str, list[TrialSpec]]]:
    """What is left of ``specs`` given the records ``done``: the replicas that need no simulation (their
    simulation is already recorded), the trials to simulate, and per simulated trial the trials that replicate it."""
    groups = group(specs) if reuse_identical else {(t.key,): [t] for t in specs}
    immediate: list[dict[str, Any]] = []
    todo: list[TrialSpec] = []
    followers: dict[str, list[TrialSpec]] = {}
    for members in groups.values():
        missing = [t for t in members if t.key not in done]
        if not missing:
            continue
        source = next((done[t.key] for t in members if t.key in done), None)
        if source is not None:
            immediate += [replica(source, t) for t in missing]
        else:
            todo.append(missing[0])
            followers[missing[0].key] = missing[1:]
    todo.sort(key=lambda t: t.index)
    return immediate, todo, followers


@contextmanager
def _progress_bar(enabled: bool, total: int, completed: int) -> Iterator[Callable[[], None]]:
    """A rich progress bar on stderr (or nothing); yields the function that advances it by one trial."""
    if not enabled:
        yield lambda: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, ProgressColumn, Task, TextColumn
    from rich.text import Text

    from softsig_service.experiments.progress import Progress as Meter

    meter = Meter(total, start=completed)

    class RateColumn(ProgressColumn):  # rate and time left of this run's trials (resumed ones count neither)
        def render(self, task: Task) -> Text:
            meter.update(int(task.completed))
            return Text(meter.message().split(", ", 1)[1] if meter.rate is not None else "")

    bar = Progress(TextColumn("trials"), BarColumn(), MofNCompleteColumn(), RateColumn(), console=Console(stderr=True))
    task = bar.add_task("trials", total=total, completed=completed)
    with bar:
        yield lambda: bar.advance(task)


def _execute(
    todo: list[TrialSpec], backend: str, workers: int, address: str | None, settings: Settings | None
) -> Iterator[dict[str, Any]]:
    if not todo:
        return
    if backend == "ray":
        yield from _execute_ray(todo, workers, address, settings)
    elif workers == 1:
        _worker_init()
        for t in todo:
            yield run_trial_spec(t, settings)
    else:
        yield from _execute_pool(todo, workers, settings)


def _execute_pool(todo: list[TrialSpec], workers: int, settings: Settings | None) -> Iterator[dict[str, Any]]:
    """A spawn-context process pool; at most ``2 * workers`` trials in flight (an interrupt loses little)."""
    ctx = get_context("spawn")
    pending: set[Future[dict[str, Any]]] = set()
    queue = iter(todo)
    with ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=ctx, initializer=_worker_init) as pool:
        try:
            for t in queue:
                pending.add(pool.submit(run_trial_spec, t, settings))
                if len(pending) >= 2 * workers:
                    break
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    yield f.result()
                    nxt = next(queue, None)
                    if nxt is not None:
                        pending.add(pool.submit(run_trial_spec, nxt, settings))
        finally:
            for f in pending:
                f.cancel()


def _execute_ray(
    todo: list[TrialSpec], workers: int, address: str | None, settings: Settings | None
) -> Iterator[dict[str, Any]]:
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
        pending = [remote.remote(t, settings) for t in todo]
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
