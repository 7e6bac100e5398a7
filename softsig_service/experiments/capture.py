"""The capture model of a hand on an object, from MuJoCo grasp simulations over a grid of relative poses.

For each relative yaw ``theta`` of the grid (:mod:`softsig_service.signatures.capture` for the coordinates) the
planner places the hand at ``(theta, 0, 0)`` on the nominal object (its usual descent, IK and collision checks:
``PlanRequest.relative_pose``); then, for each offset ``(u, v)`` of the grid, the object is moved so that its
centre lies at ``(u, v)`` from the hand's placement point along the hand's axes, and the grasp is rolled out and
judged as in a campaign trial (docs/design.md §7: approach, closure, lift, hold; carried or not). The hand's
descent is the one planned for the nominal object, as it is under pose noise. ``holdout`` further simulations at
uniformly drawn ``(theta, u, v)`` measure how often the interpolated model predicts their outcome.

Cost: ``n_theta * (2 * half_width / step + 1)^2 + holdout`` simulations (12 x 49 + 60 = 648 by default), run in
``workers`` processes.
"""

from __future__ import annotations

import functools
import json
import math
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from softsig_service.config import Settings
from softsig_service.errors import InvalidInput, SoftsigError
from softsig_service.objects import TableObject
from softsig_service.signatures.capture import (
    MIN_CAPTURE_STEP,
    CaptureModel,
    FloatArray,
    agreement,
    theta_axis,
    uniform_axis,
)

CaptureSample = tuple[float, float, float, bool]
"""``(theta [rad], u [m], v [m], carried)``."""


@dataclass(frozen=True)
class CaptureGrid:
    """The simulations of a capture model: ``n_theta`` yaws over a half turn, offsets ``-half_width ..
    half_width`` [m] in steps of ``step`` [m] along both hand axes, ``holdout`` random checks (seeded)."""

    n_theta: int = 12
    half_width: float = 0.03
    step: float = 0.01
    holdout: int = 60
    seed: int = 0

    def __post_init__(self) -> None:
        if not 2 <= self.n_theta <= 72:
            raise InvalidInput("must be within [2, 72]", field="n_theta", value=self.n_theta)
        if not MIN_CAPTURE_STEP <= self.step <= 0.1:
            raise InvalidInput(f"must be within [{MIN_CAPTURE_STEP:g}, 0.1] m", field="step", value=self.step)
        if not (self.step <= self.half_width <= 0.1):
            raise InvalidInput("need step <= half_width <= 0.1 m", field="half_width", value=self.half_width)
        if not 0 <= self.holdout <= 10_000:
            raise InvalidInput("must be within [0, 10000]", field="holdout", value=self.holdout)

    @property
    def offsets(self) -> FloatArray:
        """The offsets [m] along each hand axis."""
        return uniform_axis(self.half_width, self.step)

    @property
    def simulations(self) -> int:
        """How many grasps the grid and the held-out checks simulate (counted, nothing allocated)."""
        per_axis = 2 * round(self.half_width / self.step) + 1  # len(self.offsets)
        return self.n_theta * per_axis**2 + self.holdout


def simulate_relative_yaw(
    hand: str,
    obj_json: dict[str, Any],
    theta: float,
    offsets: list[tuple[float, float]],
    plan_options: dict[str, Any],
    settings: Settings | None = None,
) -> list[CaptureSample]:
    """One yaw: plan the hand at ``(theta, 0, 0)`` once, then roll out each object offset ``(u, v)``, under
    ``settings`` (model limits, robots folder; default: the built-in ones)."""
    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()
    from softsig_service.experiments.trial import default_planner, run_trial
    from softsig_service.objects import object_from_json
    from softsig_service.planning.request import PlanRequest
    from softsig_service.simulation.rollout import Perturbation

    obj = object_from_json(obj_json)
    planner = default_planner(settings)
    plan = planner.plan(PlanRequest(hand=hand, obj=obj, strategy="S", relative_pose=(theta, 0.0, 0.0), **plan_options))
    out: list[CaptureSample] = []
    if not plan.success or plan.grasp_pose is None:
        return [(theta, u, v, False) for u, v in offsets]
    R = np.asarray(plan.grasp_frame_pose if plan.grasp_frame_pose is not None else plan.grasp_pose)[:3, :3]
    for u, v in offsets:
        shift = u * R[:, 0] + v * R[:, 1]
        pert = Perturbation(d_yaw=0.0, dx=float(shift[0]), dy=float(shift[1]))
        result = run_trial(hand, obj, "S", seed=0, planner=planner, settings=settings, plan=plan, perturbation=pert)
        out.append((theta, u, v, result.success))
    return out


SHIPPED_DIR = "capture"
"""Folder of a hand (``hands/<name>/capture/<object>.json``) holding capture models built with the default grid
for the built-in objects at the campaign's nominal pose (``softsig signature capture``, README of the hand)."""


def shipped_capture_path(hand_ref: str, object_name: str, settings: Settings | None = None) -> Path | None:
    """The capture model shipped with the hand ``hand_ref`` (built-in name or path to its ``hand.toml``) for the
    built-in object ``object_name``, or None."""
    from softsig_service.hands.model import builtin_hand_names, builtin_hands_dir

    if hand_ref in builtin_hand_names(settings):
        folder = builtin_hands_dir(settings) / hand_ref
    elif Path(hand_ref).is_file():
        folder = Path(hand_ref).parent
    else:
        return None
    path = folder / SHIPPED_DIR / f"{object_name}.json"
    return path if path.is_file() else None


def shipped_capture_for(folder: Path, obj: TableObject) -> Path | None:
    """The capture model shipped in a hand's folder (``folder/capture/*.json``) for an object of ``obj``'s shape,
    size, mass and friction (``TableObject.shape_digest`` of the model's ``meta.object``; the pose does not
    matter: a capture model is a function of the object's pose relative to the hand), or None. What both the CLI
    and the service fall back on for strategy R when no capture model of the hand's revision is stored."""
    for path in sorted((folder / SHIPPED_DIR).glob("*.json")):
        if _shipped_digest(str(path), path.stat().st_mtime_ns) == obj.shape_digest:
            return path
    return None


@functools.lru_cache(maxsize=256)
def _shipped_digest(path: str, mtime_ns: int) -> str | None:
    """The shape digest of the object a shipped capture model was built for (cached by file and modification)."""
    from softsig_service.objects import object_from_json

    try:
        return object_from_json(json.loads(Path(path).read_text(encoding="utf-8"))["meta"]["object"]).shape_digest
    except (OSError, ValueError, KeyError, TypeError, SoftsigError):
        return None


def matching_shipped_capture(
    path: Path, obj_json: dict[str, Any], grid: CaptureGrid, plan_options: dict[str, Any]
) -> str | None:
    """The text of the shipped model at ``path`` if it was built for this object (pose included), grid and plan
    options, else None."""
    try:
        text = path.read_text(encoding="utf-8")
        meta = json.loads(text).get("meta", {})
    except (OSError, ValueError):
        return None
    same = meta.get("object") == obj_json and meta.get("grid") == asdict(grid)
    return text if same and meta.get("plan_options") == plan_options else None


def build_capture_model(
    hand: str,
    obj_json: dict[str, Any],
    grid: CaptureGrid | None = None,
    *,
    workers: int = 1,
    plan_options: dict[str, Any] | None = None,
    progress: Callable[[int, int], None] | None = None,
    settings: Settings | None = None,
) -> CaptureModel:
    """Simulate the grid (module docstring) and return the capture model of ``hand`` on the object ``obj_json``
    (object JSON; its nominal pose is where the simulations happen). ``plan_options``: further
    :class:`~softsig_service.planning.planner.PlanRequest` fields (``placement``...). ``settings``: the model
    limits and robots folder the simulations load under (default: the built-in ones)."""
    grid = grid or CaptureGrid()
    options = dict(plan_options or {})
    thetas = theta_axis(grid.n_theta)
    us = grid.offsets
    offsets = [(float(u), float(v)) for u in us for v in us]
    rng = np.random.default_rng(grid.seed)
    hold = [
        (float(rng.uniform(-math.pi / 2, math.pi / 2)), float(rng.uniform(-grid.half_width, grid.half_width)),
         float(rng.uniform(-grid.half_width, grid.half_width)))
        for _ in range(grid.holdout)
    ]  # fmt: skip
    # one task per grid yaw (all offsets), then one per held-out pose; results come back in this order
    yaws = [float(t) for t in thetas] + [t for t, _, _ in hold]
    task_offsets = [offsets] * len(thetas) + [[(u, v)] for _, u, v in hold]
    total = grid.simulations
    t0 = time.perf_counter()
    samples: list[CaptureSample] = []

    def run(mapper: Callable[..., Iterator[list[CaptureSample]]]) -> None:
        n = len(yaws)
        args = ([hand] * n, [obj_json] * n, yaws, task_offsets, [options] * n, [settings] * n)
        for result in mapper(simulate_relative_yaw, *args):
            samples.extend(result)
            if progress is not None:
                progress(len(samples), total)

    if workers <= 1:
        run(map)
    else:
        with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
            run(pool.map)
    n_grid = len(thetas) * len(offsets)
    values = np.array([carried for *_, carried in samples[:n_grid]], dtype=np.float64).reshape(
        len(thetas), len(us), len(us)
    )
    held_out = samples[n_grid:]
    model = CaptureModel(thetas, us, us, values)
    meta = {
        "hand": hand,
        "object": obj_json,
        "grid": asdict(grid),
        "plan_options": options,
        "simulations": total,
        "seconds": time.perf_counter() - t0,
        "carried_fraction": float(values.mean()),
        "holdout_agreement": agreement(model, held_out),
        "holdout": [list(s) for s in held_out],
    }
    return CaptureModel(thetas, us, us, values, meta)
