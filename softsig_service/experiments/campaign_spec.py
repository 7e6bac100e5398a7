"""The specification of a validation campaign (docs/design.md §7): its conditions, objects,
strategies, trials and seeds, and the paper's Table I.

* **Seeds**: trial ``k`` of cell ``(i, j, s)`` (condition, object and strategy indices) gets
  ``SeedSequence(entropy=seed, spawn_key=(i, j, s, k)).generate_state(1, uint32)[0]``: deterministic, independent
  between cells (S and C see independent perturbations, as Fisher's test assumes), echoed in every record.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from softsig_service.errors import InvalidInput

Condition = tuple[float, float]
"""(sigma_r [rad], sigma_t [m])."""

TABLE1_CONDITIONS: tuple[Condition, ...] = ((0.0, 0.0), (0.1, 0.01), (0.2, 0.02))
"""The paper's three uncertainty levels (docs/design.md §7)."""
TABLE1_OBJECTS: tuple[str, ...] = ("box", "apple", "cylinder")
STRATEGY_NAMES: tuple[str, ...] = ("S", "C")
"""The strategies a campaign runs by default (the paper's); it may run any of the planner's
(:data:`~softsig_service.planning.strategies.STRATEGIES`): R uses the hand's capture model on each object
(``capture/<object>.json`` in the campaign folder, copied or built by the campaign when missing)."""
TABLE1_CELLS = len(TABLE1_CONDITIONS) * len(TABLE1_OBJECTS) * len(STRATEGY_NAMES)
"""Cells of the reference experiment's grid (condition x object x strategy): 18."""
CAPTURE_DIR = "capture"
PAPER_TABLE1: dict[str, tuple[tuple[int, int], ...]] = {
    "box": ((17, 20), (15, 16), (3, 11)),
    "apple": ((20, 20), (19, 19), (17, 15)),
    "cylinder": ((18, 19), (10, 16), (8, 11)),
}
"""The paper's real-robot successes (S, C) out of :data:`PAPER_TRIALS` per condition of
:data:`TABLE1_CONDITIONS` (docs/design.md §7)."""
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
    capture_file: str = ""
    """Strategy R: the capture model's JSON file (set by the campaign runner)."""

    @property
    def key(self) -> str:
        """A stable identifier: ``c<condition>/<object>/<strategy>/<trial>``."""
        return f"c{self.condition}/{self.object}/{self.strategy}/{self.trial}"


def plan_option_fields(cs_method: str, criterion: str, placement: str) -> dict[str, str]:
    """The :class:`~softsig_service.planning.planner.PlanRequest` fields of the closure-signature method, its
    criterion and the placement, as campaigns and the command line name them (validated by the request)."""
    return {"cs_method": cs_method, "cs_criterion": criterion, "placement": placement}


def plan_options(spec: TrialSpec | CampaignSpec) -> dict[str, Any]:
    """The :class:`~softsig_service.planning.planner.PlanRequest` fields set by a campaign or one of its trials."""
    return plan_option_fields(spec.cs_method, spec.criterion, spec.placement)


def trial_seed(seed: int, cell: Sequence[int], trial: int) -> int:
    """The seed of trial ``trial`` of the cell with indices ``cell``: ``SeedSequence(seed, spawn_key=(*cell,
    trial))``'s first 32-bit word (deterministic; distinct streams for distinct keys)."""
    ss = np.random.SeedSequence(entropy=seed, spawn_key=(*cell, trial))
    return int(ss.generate_state(1, dtype=np.uint32)[0])


_SHARED_WITH_TRIALS = ("hand", "x", "y", "yaw", "cs_method", "criterion", "placement")
"""The fields of a :class:`CampaignSpec` that every one of its :class:`TrialSpec` carries as they are."""


@dataclass(frozen=True)
class CampaignSpec:
    """A campaign grid. ``objects`` are built-in names (docs/design.md §7, or the household meshes) placed at
    ``(x, y, yaw)`` [m, m, rad].

    ``cs_method`` ("ellipsoid" | "pca" | "mesh"), ``criterion`` (the ellipsoid CS's "absolute" | "relative") and
    ``placement`` ("open_centre" | "grasp_centre" | "knuckle" | "per_strategy"; "previous" its deprecated name)
    are passed to every plan (see :class:`PlanRequest`)."""

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
        from softsig_service.objects import OBJECT_NAMES
        from softsig_service.planning.hand_model import PLACEMENTS
        from softsig_service.planning.strategies import STRATEGIES
        from softsig_service.signatures.closure_types import CRITERIA, METHODS

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
            if name not in OBJECT_NAMES:
                raise InvalidInput("unknown object", field="objects", value=name, choices=OBJECT_NAMES)
        for s in self.strategies:
            if s not in STRATEGIES:
                raise InvalidInput("unknown strategy", field="strategies", value=s, choices=STRATEGIES)
        if len(set(self.strategies)) != len(self.strategies):
            raise InvalidInput("a strategy is named twice", field="strategies", value=list(self.strategies))

    def trial_specs(self) -> list[TrialSpec]:
        """Every trial, in the order condition, object, strategy, trial."""
        out: list[TrialSpec] = []
        shared = {name: getattr(self, name) for name in _SHARED_WITH_TRIALS}
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
                                **shared,
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
