"""Trials of a campaign that are the same simulation: simulated once, recorded for each.

A campaign trial is a deterministic function of its inputs (the rollout's module docstring): the hand, the object
and its nominal pose, the strategy and its plan options (with R: its capture model and the condition's sigmas) and
the perturbation drawn from the trial's seed. Where the sigmas are 0 every seed draws the zero perturbation, so all
the trials of such a cell (the paper's nominal condition: a whole column of Table I) are one simulation repeated.
:func:`simulation_key` names what a trial's outcome depends on; :func:`group` collects the trials that share it, so
a campaign simulates the first of each group and records its outcome for the others as *replicas*: the same record
with the replica's own ``key``, ``index``, ``condition``, ``trial`` and ``seed``, ``same_as`` naming the trial that
was simulated, and zero wall time (nothing ran for it).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any

from softsig_service.experiments.campaign_spec import TrialSpec
from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()  # the rollout module imports MuJoCo: its GL backend is chosen first

from softsig_service.simulation.rollout import Perturbation  # noqa: E402

SimulationKey = tuple[Any, ...]
"""What a trial's outcome depends on (hashable)."""

_LABELS = ("index", "condition", "trial", "seed")
"""The fields of a :class:`TrialSpec` that label a trial without changing its simulation (the seed acts only
through the perturbation it draws)."""


def simulation_key(spec: TrialSpec) -> SimulationKey:
    """Every input of ``spec``'s simulation: its fields but the labels, and the perturbation its seed draws
    (``d_yaw`` [rad], ``dx``, ``dy`` [m]; -0.0 and 0.0 are the same key, and the same simulation)."""
    fields = dataclasses.asdict(spec)
    for name in _LABELS:
        del fields[name]
    p = Perturbation.draw(spec.seed, spec.sigma_r, spec.sigma_t)
    return (*sorted(fields.items()), ("perturbation", (p.d_yaw, p.dx, p.dy)))


def group(specs: Iterable[TrialSpec]) -> dict[SimulationKey, list[TrialSpec]]:
    """The trials by simulation, each group in the order given (its first is the one to simulate)."""
    out: dict[SimulationKey, list[TrialSpec]] = {}
    for spec in specs:
        out.setdefault(simulation_key(spec), []).append(spec)
    return out


def replica(record: dict[str, Any], spec: TrialSpec) -> dict[str, Any]:
    """The record of trial ``spec``, whose simulation is ``record``'s: the same outcome under its own labels."""
    out = dict(record)
    out.update(
        key=spec.key,
        index=spec.index,
        condition=spec.condition,
        trial=spec.trial,
        seed=spec.seed,
        same_as=record.get("same_as", record["key"]),
        wall_time=0.0,
        timing={},
    )
    return out
