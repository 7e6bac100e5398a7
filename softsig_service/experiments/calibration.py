"""Calibration of a simulated hand to real grasp outcomes, checked on outcomes it was not fitted to.

**What moves.** The parameters the hand's manifest declares (``[calibration]``, :mod:`softsig_service.hands.
calibration`), each within its declared range (a request may narrow a range, never widen it); one value of each
for every object and strategy. Nothing else.

**The objective.** The real outcomes are cells (object, strategy, sigma_r, sigma_t: ``k`` of ``n`` successes,
:mod:`~softsig_service.experiments.outcomes`). For a parameter set each *fitted* cell is simulated: a cell with
pose noise by ``trials_per_cell`` trials whose perturbations come from fixed seeds (the same seeds for every
parameter set: common random numbers, so two parameter sets differ by the model, not by the draws), a cell
without noise by one simulation (all its trials are that simulation), and a real trial whose offset was measured
by one simulation at that offset (in a cell with measured offsets, its trials without one are not scored). The
objective is the sum over fitted cells of the beta-binomial log-likelihood of the real counts given the simulated
ones (:mod:`~softsig_service.experiments.likelihood`), which carries the simulation's own Monte Carlo noise.

**The search.** Optuna's TPE sampler (seeded), asked and told one parameter set at a time; the uncalibrated
model (every parameter at its default) is the first set evaluated. The budget is in simulations: as many sets as
``budget`` allows at the cost of one set. The best set by the objective is the calibrated model. A range narrowed
past a parameter's default leaves the uncalibrated model out of the search; it is then simulated on the fitted
cells apart.

**Held out.** The cells any ``held_out`` selector matches are never simulated during the fit. After it, they are
simulated ``test_trials`` times (their own seeds, the same for both models) with the calibrated and the
uncalibrated model, and scored with the same beta-binomial log-likelihood, beside a constant-rate baseline (one
rate for every cell: the fitted cells' pooled real rate, with the Jeffreys prior).
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from softsig_service.config import Settings
from softsig_service.errors import InvalidInput
from softsig_service.experiments.campaign_spec import trial_seed
from softsig_service.experiments.likelihood import (
    beta_binomial_logpmf,
    binomial_logpmf,
    jeffreys_interval,
    predicted_rate,
)
from softsig_service.experiments.outcomes import CellKey, CellSelector, RealOutcomes, split_cells
from softsig_service.experiments.statistics import wilson_interval
from softsig_service.hands.calibration import CalibrationParameter
from softsig_service.hands.model import load_hand
from softsig_service.hands.variant import write_variant

MAX_EVALUATIONS = 500
"""The most parameter sets one calibration evaluates."""
RESULT_JSON = "calibration.json"
EVALUATIONS_FILE = "evaluations.jsonl"
VARIANT_DIR = "variant"

ProgressCallback = Callable[[int, int, str], None]
"""Called with (simulations done, simulations planned, a message)."""


@dataclass(frozen=True)
class CalibrationSpec:
    """A calibration's inputs (module docstring). ``hand``: a built-in name or a path to its ``hand.toml``;
    ``parameters``: the declared names to fit (empty: all); ``ranges``: narrower [low, high] per name;
    ``budget``: simulations for the fit; ``trials_per_cell`` / ``test_trials``: simulations of a noisy fitted /
    held-out cell per parameter set; ``name``: the calibrated variant's name (default ``<hand>_calibrated``);
    ``placement`` and ``cs_method``: the plan options of every simulated trial; ``x, y, yaw``: the object's
    nominal pose [m, m, rad] (the campaign's)."""

    hand: str
    outcomes: RealOutcomes
    held_out: tuple[CellSelector, ...] = ()
    parameters: tuple[str, ...] = ()
    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    budget: int = 2000
    trials_per_cell: int = 20
    test_trials: int = 40
    seed: int = 0
    name: str = ""
    placement: str = "open_centre"
    cs_method: str = "ellipsoid"
    x: float = 0.5
    y: float = 0.0
    yaw: float = 0.0
    outcomes_version: int | None = None
    """The registry version the outcomes were read from (provenance), if any."""

    def to_json_dict(self) -> dict[str, Any]:
        """The inputs as JSON (stored with the result)."""
        return {
            "hand": self.hand,
            "outcomes": self.outcomes.model_dump(mode="json"),
            "outcomes_version": self.outcomes_version,
            "held_out": [s.model_dump(mode="json", exclude_none=True) for s in self.held_out],
            "parameters": list(self.parameters),
            "ranges": {k: list(v) for k, v in self.ranges.items()},
            "budget": self.budget,
            "trials_per_cell": self.trials_per_cell,
            "test_trials": self.test_trials,
            "seed": self.seed,
            "name": self.name,
            "placement": self.placement,
            "cs_method": self.cs_method,
            "pose": [self.x, self.y, self.yaw],
        }


@dataclass(frozen=True)
class Free:
    """A parameter the calibration chooses: its declaration and the range searched."""

    parameter: CalibrationParameter
    low: float
    high: float


@dataclass(frozen=True)
class Simulation:
    """One simulated trial of a calibration: which cell, which draw (or measured offset)."""

    cell: CellKey
    seed: int
    offset: tuple[float, float, float] | None = None


@dataclass
class CellScore:
    """A cell's real counts and, per model, its simulated counts."""

    key: CellKey
    held_out: bool
    real: tuple[int, int]
    simulated: dict[str, tuple[int, int]] = field(default_factory=dict)
    loglik: dict[str, float] = field(default_factory=dict)


def free_parameters(spec: CalibrationSpec) -> tuple[list[Free], dict[str, float]]:
    """The searched parameters and the defaults of all declared ones; :class:`InvalidInput` naming the field for
    a hand without declarations, an undeclared name or a range outside the declared one."""
    hand = load_hand(spec.hand)
    section = hand.manifest.calibration
    if section is None or not section.parameters:
        raise InvalidInput(
            "the hand declares no calibration parameters ([calibration] in hand.toml)", field="hand", value=hand.name
        )
    declared = {p.name: p for p in section.parameters}
    for k, name in enumerate(spec.parameters):
        if name not in declared:
            raise InvalidInput(
                "not a declared parameter", field=f"parameters[{k}]", value=name, choices=sorted(declared)
            )
    for name, rng in spec.ranges.items():
        if name not in declared:
            raise InvalidInput("not a declared parameter", field=f"ranges.{name}", value=name, choices=sorted(declared))
        lo, hi = (float(v) for v in rng)
        d_lo, d_hi = declared[name].range
        if not (math.isfinite(lo) and math.isfinite(hi) and d_lo <= lo < hi <= d_hi):
            raise InvalidInput(
                f"a range must lie within the declared [{d_lo}, {d_hi}] with low < high",
                field=f"ranges.{name}",
                value=[lo, hi],
            )
    names = list(spec.parameters) or list(declared)
    free = []
    for name in names:
        p = declared[name]
        lo, hi = spec.ranges.get(name, p.range)
        free.append(Free(p, float(lo), float(hi)))
    defaults = {p.name: p.default for p in section.parameters}
    return free, defaults


def plan_simulations(spec: CalibrationSpec, cells: Sequence[CellKey], per_cell: int, salt: int) -> list[Simulation]:
    """The simulations of ``cells``: measured offsets one each, a noiseless cell once, a noisy one ``per_cell``
    draws from seeds fixed by (``spec.seed``, the cell's index among all cells, ``salt``, the draw)."""
    every = sorted(spec.outcomes.counts())
    out: list[Simulation] = []
    for key in cells:
        index = every.index(key)
        measured = [t for t in spec.outcomes.trial_records(key) if t.offset is not None]
        if measured:
            out += [Simulation(key, 0, (t.offset.d_yaw, t.offset.dx, t.offset.dy)) for t in measured if t.offset]
            continue
        n = 1 if key[2] == 0.0 and key[3] == 0.0 else per_cell
        out += [Simulation(key, trial_seed(spec.seed, (index, salt), k)) for k in range(n)]
    return out


def _simulate_one(hand_toml: str, spec: CalibrationSpec, sim: Simulation, settings: Settings | None) -> bool:
    """One trial's verdict (run in a worker process)."""
    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()
    from softsig_service.experiments.trial import run_trial
    from softsig_service.objects import builtin_object
    from softsig_service.simulation.rollout import Perturbation

    obj_name, strategy, sigma_r, sigma_t = sim.cell
    obj = builtin_object(obj_name, x=spec.x, y=spec.y, yaw=spec.yaw)
    pert = Perturbation(*sim.offset) if sim.offset is not None else None
    result = run_trial(
        hand_toml,
        obj,
        strategy,  # type: ignore[arg-type]
        seed=sim.seed,
        sigma_r=sigma_r,
        sigma_t=sigma_t,
        plan_options={"placement": spec.placement, "cs_method": spec.cs_method},
        perturbation=pert,
        settings=settings,
    )
    return bool(result.success)


@contextmanager
def _runner(workers: int) -> Iterator[Callable[[Callable[..., bool], list[tuple[Any, ...]]], list[bool]]]:
    """A map over simulations: in this process for one worker, else a spawn pool kept for the whole calibration."""
    from softsig_service.gl_backend import prepare_mujoco

    if workers <= 1:
        prepare_mujoco()
        yield lambda fn, args: [fn(*a) for a in args]
        return
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn"), initializer=prepare_mujoco) as pool:
        yield lambda fn, args: list(pool.map(fn, *zip(*args, strict=True))) if args else []


def _tally(
    cells: Sequence[CellKey], sims: Sequence[Simulation], verdicts: Sequence[bool]
) -> dict[CellKey, tuple[int, int]]:
    """Simulated successes and simulations per cell of ``cells``."""
    counts: dict[CellKey, list[int]] = {c: [0, 0] for c in cells}
    for sim, ok in zip(sims, verdicts, strict=True):
        counts[sim.cell][0] += int(ok)
        counts[sim.cell][1] += 1
    return {c: (v[0], v[1]) for c, v in counts.items()}


def _score(
    cells: Sequence[CellKey],
    sims: Sequence[Simulation],
    verdicts: Sequence[bool],
    real: Mapping[CellKey, tuple[int, int]],
    outcomes: RealOutcomes,
) -> tuple[float, dict[CellKey, tuple[int, int]], dict[CellKey, float]]:
    """The summed beta-binomial log-likelihood of ``cells``, the simulated counts and each cell's term."""
    counts = _tally(cells, sims, verdicts)
    terms: dict[CellKey, float] = {}
    for c in cells:
        measured = [t for t in outcomes.trial_records(c) if t.offset is not None]
        if measured:  # each measured trial against its own simulation
            mine = [ok for sim, ok in zip(sims, verdicts, strict=True) if sim.cell == c]
            terms[c] = sum(
                beta_binomial_logpmf(int(t.success), 1, int(ok), 1) for t, ok in zip(measured, mine, strict=True)
            )
        else:
            k, n = real[c]
            terms[c] = beta_binomial_logpmf(k, n, *counts[c])
    return float(sum(terms.values())), counts, terms


@dataclass
class CalibrationResult:
    """What a calibration found (JSON: :meth:`to_json_dict`)."""

    spec: CalibrationSpec
    free: list[Free]
    defaults: dict[str, float]
    best: dict[str, float]
    evaluations: list[dict[str, Any]]
    cells: list[CellScore]
    heldout_loglik: dict[str, float]
    fitted_loglik: dict[str, float]
    constant_rate: float
    simulations: int
    wall_time: float
    variant: Path | None = None
    files: dict[str, str] = field(default_factory=dict)

    def to_json_dict(self) -> dict[str, Any]:
        """Everything needed to read or redraw the result."""
        return {
            "spec": self.spec.to_json_dict(),
            "parameters": [
                {
                    "name": f.parameter.name,
                    "kind": f.parameter.kind,
                    "unit": f.parameter.unit,
                    "declared_range": list(f.parameter.range),
                    "searched_range": [f.low, f.high],
                    "default": f.parameter.default,
                    "calibrated": self.best[f.parameter.name],
                    "source": f.parameter.source,
                }
                for f in self.free
            ],
            "defaults": self.defaults,
            "calibrated": self.best,
            "split": {
                "fitted": [list(c.key) for c in self.cells if not c.held_out],
                "held_out": [list(c.key) for c in self.cells if c.held_out],
            },
            "heldout_loglik": self.heldout_loglik,
            "fitted_loglik": self.fitted_loglik,
            "constant_rate": self.constant_rate,
            "cells": [
                {
                    "object": c.key[0],
                    "strategy": c.key[1],
                    "sigma_r": c.key[2],
                    "sigma_t": c.key[3],
                    "held_out": c.held_out,
                    "real": list(c.real),
                    "real_interval": list(wilson_interval(*c.real)),
                    "simulated": {m: list(v) for m, v in c.simulated.items()},
                    "predicted": {m: predicted_rate(*v) for m, v in c.simulated.items()},
                    "predicted_interval": {m: list(jeffreys_interval(*v)) for m, v in c.simulated.items()},
                    "loglik": c.loglik,
                }
                for c in self.cells
            ],
            "evaluations": self.evaluations,
            "simulations": self.simulations,
            "wall_time": self.wall_time,
            "variant": str(self.variant) if self.variant else None,
        }


def check_spec(spec: CalibrationSpec) -> tuple[list[Free], dict[str, float], list[CellKey], list[CellKey], int]:
    """Validate ``spec`` before anything runs: (free parameters, defaults, fitted cells, held-out cells,
    parameter sets the budget allows). :class:`InvalidInput` naming the field."""
    for name, value, low in (
        ("budget", spec.budget, 1),
        ("trials_per_cell", spec.trials_per_cell, 1),
        ("test_trials", spec.test_trials, 1),
        ("seed", spec.seed, 0),
    ):
        if value < low:
            raise InvalidInput(f"must be >= {low}", field=name, value=value)
    free, defaults = free_parameters(spec)
    real = spec.outcomes.counts()
    fitted, test = split_cells(list(real), spec.held_out)
    if not fitted:
        raise InvalidInput("every cell is held out: nothing to fit", field="held_out")
    per_set = len(plan_simulations(spec, fitted, spec.trials_per_cell, 0))
    n_sets = min(MAX_EVALUATIONS, spec.budget // per_set)
    if n_sets < 2:
        raise InvalidInput(
            f"the budget allows fewer than 2 parameter sets (one costs {per_set} simulations)",
            field="budget",
            value=spec.budget,
        )
    return free, defaults, fitted, test, n_sets


def _defaults_searched(free: Sequence[Free], defaults: Mapping[str, float]) -> bool:
    """Whether the uncalibrated model lies in the searched ranges (then it is the first set evaluated; otherwise it
    is evaluated on the fitted cells apart from the search)."""
    return all(f.low <= defaults[f.parameter.name] <= f.high for f in free)


def _planned(n_sets: int, fit: int, test: int, defaults_searched: bool) -> int:
    """Simulations of a calibration: ``n_sets`` parameter sets of ``fit`` each, the uncalibrated model's own
    ``fit`` when it is not among them, and the held-out ``test`` for both models."""
    return n_sets * fit + (0 if defaults_searched else fit) + 2 * test


def planned_simulations(spec: CalibrationSpec) -> int:
    """How many simulations :func:`calibrate` runs for ``spec`` (checked by :func:`check_spec` first)."""
    free, defaults, fitted, test, n_sets = check_spec(spec)
    fit = len(plan_simulations(spec, fitted, spec.trials_per_cell, 0))
    return _planned(
        n_sets, fit, len(plan_simulations(spec, test, spec.test_trials, 1)), _defaults_searched(free, defaults)
    )


def calibrate(
    spec: CalibrationSpec,
    out: Path,
    *,
    workers: int = 1,
    progress: ProgressCallback | None = None,
    settings: Settings | None = None,
) -> CalibrationResult:
    """Run the calibration of ``spec`` (module docstring), writing into ``out``: ``evaluations.jsonl`` (one line
    per parameter set), ``variant/<name>/hand.toml`` (the calibrated hand) and ``calibration.json``; the report
    and figure are :mod:`~softsig_service.experiments.calibration_report`'s. ``workers`` > 1 simulates in a pool
    of spawned processes (a job's cancellation kills them with the job's process group)."""
    import optuna

    t0 = time.perf_counter()
    free, defaults, fitted, test, n_sets = check_spec(spec)
    hand = load_hand(spec.hand)
    name = spec.name or f"{hand.name}_calibrated"[:64]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for stale in (out / VARIANT_DIR, out / "sets"):
        shutil.rmtree(stale, ignore_errors=True)
    real = spec.outcomes.counts()
    fit_sims = plan_simulations(spec, fitted, spec.trials_per_cell, 0)
    test_sims = plan_simulations(spec, test, spec.test_trials, 1)
    searched = _defaults_searched(free, defaults)
    planned = _planned(n_sets, len(fit_sims), len(test_sims), searched)
    done = 0

    def report(message: str) -> None:
        if progress is not None:
            progress(done, planned, message)

    def run(values: Mapping[str, float], sims: list[Simulation], label: str) -> list[bool]:
        nonlocal done
        folder = out / "sets" / label / name
        toml = write_variant(hand.folder, hand.manifest, folder, name, values, {"calibration_set": label})
        try:
            verdicts = runner(_simulate_one, [(str(toml), spec, s, settings) for s in sims])
        finally:
            shutil.rmtree(folder.parent, ignore_errors=True)
        done += len(sims)
        return verdicts

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    sampler = optuna.samplers.TPESampler(seed=spec.seed, n_startup_trials=max(2, min(10, n_sets // 3)))
    study = optuna.create_study(direction="maximize", sampler=sampler)
    if searched:  # the uncalibrated model is the first set
        study.enqueue_trial({f.parameter.name: defaults[f.parameter.name] for f in free})
    evaluations: list[dict[str, Any]] = []
    sim_counts: dict[str, dict[CellKey, tuple[int, int]]] = {}
    terms_of: dict[str, dict[CellKey, float]] = {}
    best_value, best_key = -math.inf, ""
    with _runner(workers) as runner, (out / EVALUATIONS_FILE).open("w", encoding="utf-8") as sink:
        for k in range(n_sets):
            trial = study.ask()
            chosen = {f.parameter.name: trial.suggest_float(f.parameter.name, f.low, f.high) for f in free}
            label = f"{k:03d}"
            verdicts = run({**defaults, **chosen}, fit_sims, label)
            value, counts, terms = _score(fitted, fit_sims, verdicts, real, spec.outcomes)
            study.tell(trial, value)
            sim_counts[label], terms_of[label] = counts, terms
            row = {"set": k, "values": chosen, "loglik": value, "cells": [[*c, *counts[c]] for c in fitted]}
            evaluations.append(row)
            sink.write(json.dumps(row) + "\n")
            sink.flush()
            if value > best_value:
                best_value, best_key = value, label
            report(f"parameter set {k + 1} of {n_sets}: log-likelihood {value:.2f} (best {best_value:.2f})")
        best = {**defaults, **evaluations[int(best_key)]["values"]}
        uncalibrated = "000"
        if not searched:  # a narrowed range left the uncalibrated model out of the search: evaluate it apart
            uncalibrated = "uncalibrated"
            report("fitted cells with the uncalibrated model (outside the searched ranges)")
            verdicts = run(defaults, fit_sims, uncalibrated)
            _, sim_counts[uncalibrated], terms_of[uncalibrated] = _score(
                fitted, fit_sims, verdicts, real, spec.outcomes
            )
        models = {"uncalibrated": (defaults, uncalibrated), "calibrated": (best, best_key)}
        heldout: dict[str, float] = {}
        test_counts: dict[str, dict[CellKey, tuple[int, int]]] = {}
        test_terms: dict[str, dict[CellKey, float]] = {}
        for model, (values, _) in models.items():
            if test:
                report(f"predicting the {len(test)} held-out cells with the {model} model")
                verdicts = run(values, test_sims, f"test_{model}")
                heldout[model], test_counts[model], test_terms[model] = _score(
                    test, test_sims, verdicts, real, spec.outcomes
                )
    k_fit = sum(real[c][0] for c in fitted)
    n_fit = sum(real[c][1] for c in fitted)
    rate = (k_fit + 0.5) / (n_fit + 1.0)
    if test:
        heldout["constant_rate"] = float(sum(binomial_logpmf(*real[c], rate) for c in test))
    fitted_ll = {m: float(sum(terms_of[key].values())) for m, (_, key) in models.items()}
    fitted_ll["constant_rate"] = float(sum(binomial_logpmf(*real[c], rate) for c in fitted))
    cells: list[CellScore] = []
    for c in sorted(real):
        held = c in test
        score = CellScore(c, held, real[c])
        for model, (_, key) in models.items():
            score.simulated[model] = test_counts[model][c] if held else sim_counts[key][c]
            score.loglik[model] = test_terms[model][c] if held else terms_of[key][c]
        score.loglik["constant_rate"] = binomial_logpmf(*real[c], rate)
        cells.append(score)
    shutil.rmtree(out / "sets", ignore_errors=True)
    result = CalibrationResult(
        spec=spec,
        free=free,
        defaults=defaults,
        best=best,
        evaluations=evaluations,
        cells=cells,
        heldout_loglik=heldout,
        fitted_loglik=fitted_ll,
        constant_rate=rate,
        simulations=done,
        wall_time=time.perf_counter() - t0,
    )
    provenance = {
        "calibrated_from": hand.name,
        "outcomes_version": spec.outcomes_version,
        "outcomes_sha256": _digest(spec.outcomes.model_dump(mode="json")),
        "parameters": {f.parameter.name: {"range": [f.low, f.high], "source": f.parameter.source} for f in free},
        "held_out": [s.model_dump(mode="json", exclude_none=True) for s in spec.held_out],
        "fitted_cells": [list(c) for c in fitted],
        "held_out_cells": [list(c) for c in test],
        "heldout_loglik": heldout,
        "fitted_loglik": fitted_ll,
        "simulations": done,
        "seed": spec.seed,
    }
    result.variant = write_variant(hand.folder, hand.manifest, out / VARIANT_DIR / name, name, best, provenance)
    (out / RESULT_JSON).write_text(json.dumps(result.to_json_dict(), indent=1) + "\n", encoding="utf-8")
    result.files = {
        "result": RESULT_JSON,
        "evaluations": EVALUATIONS_FILE,
        "variant": str(result.variant.relative_to(out)),
    }
    return result


def _digest(data: Any) -> str:
    import hashlib

    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()


def synthetic_outcomes(
    spec: CalibrationSpec,
    values: Mapping[str, float],
    cells: Sequence[CellKey],
    trials: int,
    *,
    workers: int = 1,
    seed: int = 12345,
    settings: Settings | None = None,
) -> RealOutcomes:
    """Outcomes the simulator itself gives with parameter ``values`` on ``cells`` (``trials`` per cell, seeds of
    their own): a test case whose true parameters are known."""
    hand = load_hand(spec.hand)
    defaults = {p.name: p.default for p in (hand.manifest.calibration.parameters if hand.manifest.calibration else ())}
    from softsig_service.experiments.outcomes import RealCell

    probe = dataclasses.replace(
        spec,
        seed=seed,
        outcomes=RealOutcomes(
            cells=tuple(
                RealCell(object=c[0], strategy=c[1], sigma_r=c[2], sigma_t=c[3], trials=1, successes=0) for c in cells
            )
        ),
    )
    sims = plan_simulations(probe, list(cells), trials, 2)
    with tempfile.TemporaryDirectory(prefix="softsig_synthetic_") as folder:
        toml = write_variant(hand.folder, hand.manifest, Path(folder) / "truth", "truth", {**defaults, **values}, {})
        with _runner(workers) as runner:
            verdicts = runner(_simulate_one, [(str(toml), probe, s, settings) for s in sims])
    counts = _tally(cells, sims, verdicts)
    # a noiseless cell is one simulation: its every trial is that outcome
    return RealOutcomes(
        cells=tuple(
            RealCell(
                object=c[0],
                strategy=c[1],
                sigma_r=c[2],
                sigma_t=c[3],
                trials=trials,
                successes=counts[c][0] * trials // counts[c][1],
            )
            for c in cells
        ),
        note=f"synthetic: the simulator with {dict(values)}",
    )
