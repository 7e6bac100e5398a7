"""The pull test: the break forces of a grasp in MuJoCo (docs/design.md §5).

**Pull test** (:func:`pull_test`): the wrist is fixed (the hand's ``mount`` is welded to the world), the object
is grasped as by :func:`~softsig_service.simulation.grasp.grasp_object` (gravity off, closure command held
closed, MuJoCo's noslip solver on), then a force on the object's centre of mass (``xfrc_applied``; the centre of
the built-in shapes) grows along a unit direction ``d`` given in the hand frame until the object *leaves the
hand*: at the first simulation step where

* its centre is farther than ``displacement_threshold`` (default 0.02 m) from its grasped position (reason
  ``"displacement"``), or
* it has had no hand-object contact for ``contact_loss_time`` (default 0.01 s) in a row (``"contact_lost"``).

The **break force** is the applied force [N] at that moment. An object still held at ``cap`` (default 200 N) is
reported with ``force = cap``, ``capped = True`` (a lower bound, reason ``"cap"``). Two ways to grow the force:

* ``mode = "quasi_static"`` (default): a staircase. Levels ``start_force * growth^k`` (0.5 N x 1.25^k) up to the
  cap; each level is held until the object is at rest (speed < ``settle_speed`` after at least ``min_dwell``) or
  for at most ``max_dwell`` [s], carrying the state from one level to the next (a quasi-static loading path).
  When a level breaks the grasp, the interval between it and the last level that held is bisected (each trial
  from the state at the end of the holding level) down to ``max(resolution_abs, resolution_rel * F)``; the
  reported force is the smallest force found to break. This makes the result independent of a loading rate:
  with a continuous ramp the soft hands' break forces grow 2-3 fold between 12.5 and 100 N/s (their joint
  damping makes them lag the load) and are still not converged at 1 N/s.
* ``mode = "ramp"``: ``F(t) = rate * t`` (default 50 N/s) up to the cap, then held for ``hold_at_cap`` [s]; the
  force reported is the one applied during the step that broke the grasp (for ``"contact_lost"``: when the
  contact was first lost). Rate-dependent (see above); kept for comparison.

Every direction restarts from the same grasped state (``mj_copyData`` of the grasp's ``MjData``), so the test
is deterministic. MuJoCo's soft friction creeps under any tangential load (without the noslip solver a parallel
gripper lets the box slide out at about 10 N along its fingers, with it at about 55 N for 105 N of total grip),
which is why :class:`~softsig_service.simulation.grasp_state.GraspSettings` turns the noslip solver on.

If the hand does not hold the object alone (``Grasp.held`` False: released after the closure, it leaves the
hand with no applied force), no pull is simulated: every direction reports ``force = 0`` with reason
``"not_held"``.

**Directions** (hand frame): :data:`AXIS_DIRECTIONS` are +x, -x, +y, -y, +z, -z; :data:`SPHERE_DIRECTIONS` are
the 26 neighbours of a cube cell, ``(i, j, k) / |(i, j, k)|`` for ``i, j, k`` in ``{-1, 0, 1}`` not all zero: the 6
axis directions, the 12 edge diagonals (two non-zero components) and the 8 corner diagonals. The default
(:func:`default_directions`) is their union, which *is* the 26 (the axis directions are among them), ordered:
the 6 axes as above, then the 12 edges, then the 8 corners (each group in lexicographic order of (i, j, k)).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from typing import Any, Literal, cast

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput, SolverError
from softsig_service.signatures.stiffness_types import BreakForce
from softsig_service.simulation.grasp_state import Grasp

FloatArray = NDArray[np.float64]

BreakReason = Literal["displacement", "contact_lost", "cap", "not_held"]

AXIS_DIRECTIONS: FloatArray = np.array(
    [[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0], [0, 0, 1.0], [0, 0, -1.0]]
)
"""+x, -x, +y, -y, +z, -z (hand frame)."""


def _cube_neighbours() -> FloatArray:
    cells = [c for c in itertools.product((-1, 0, 1), repeat=3) if any(c)]
    edges = [c for c in cells if sum(1 for x in c if x) == 2]
    corners = [c for c in cells if all(c)]
    out = [*AXIS_DIRECTIONS.tolist(), *edges, *corners]
    arr = np.array(out, dtype=np.float64)
    return arr / np.linalg.norm(arr, axis=1, keepdims=True)


SPHERE_DIRECTIONS: FloatArray = _cube_neighbours()
"""The 26 neighbours of a cube cell, normalised: 6 axes, 12 edges, 8 corners (hand frame)."""


def default_directions() -> FloatArray:
    """The default pull directions (26, 3): the union of :data:`AXIS_DIRECTIONS` and :data:`SPHERE_DIRECTIONS`."""
    return SPHERE_DIRECTIONS.copy()


PullMode = Literal["quasi_static", "ramp"]
PULL_MODES: tuple[PullMode, ...] = ("quasi_static", "ramp")


@dataclass(frozen=True)
class PullSettings:
    """Pull-test settings (module docstring).

    Attributes:
        mode: ``"quasi_static"`` (staircase with settling and bisection) or ``"ramp"`` (continuous).
        cap: maximum force [N].
        displacement_threshold: the object has left the hand when its centre moved more than this [m].
        contact_loss_time: ... or when it has had no hand contact for this long [s].
        start_force, growth: staircase levels ``start_force * growth^k`` [N].
        min_dwell, max_dwell: time [s] each level is held at least / at most.
        settle_speed: a level has settled when the object is slower than this [m/s].
        resolution_abs, resolution_rel: bisection stops when the bracket is below ``max(abs [N], rel * F)``.
        rate: ramp mode: force rate [N/s]. hold_at_cap: ramp mode: time [s] held at the cap.
    """

    mode: PullMode = "quasi_static"
    cap: float = 200.0
    displacement_threshold: float = 0.02
    contact_loss_time: float = 0.01
    start_force: float = 0.5
    growth: float = 1.25
    min_dwell: float = 0.05
    max_dwell: float = 0.5
    settle_speed: float = 1e-3
    resolution_abs: float = 0.05
    resolution_rel: float = 0.01
    rate: float = 50.0
    hold_at_cap: float = 0.25

    def __post_init__(self) -> None:
        if self.mode not in PULL_MODES:
            raise InvalidInput("unknown pull mode", field="pull.mode", value=self.mode, choices=PULL_MODES)
        for name in (
            "cap",
            "displacement_threshold",
            "contact_loss_time",
            "start_force",
            "max_dwell",
            "settle_speed",
            "resolution_abs",
            "rate",
        ):
            _check(getattr(self, name), f"pull.{name}", strict=True)
        for name in ("min_dwell", "resolution_rel", "hold_at_cap"):
            _check(getattr(self, name), f"pull.{name}", strict=False)
        if not self.growth > 1.0 or not math.isfinite(self.growth):
            raise InvalidInput("must be a finite number > 1", field="pull.growth", value=self.growth)
        if self.min_dwell > self.max_dwell:
            raise InvalidInput("must not exceed max_dwell", field="pull.min_dwell", value=self.min_dwell)

    def levels(self) -> list[float]:
        """The staircase's force levels [N]: ``start_force * growth^k`` below the cap, then the cap."""
        out = []
        f = self.start_force
        while f < self.cap * (1.0 - 1e-12):
            out.append(f)
            f *= self.growth
        out.append(self.cap)
        return out

    def to_json_dict(self) -> dict[str, Any]:
        """The settings as a JSON dict (units: N, m, s, m/s, N/s)."""
        return dataclasses.asdict(self)


def _check(value: Any, field: str, *, strict: bool) -> None:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0.0 or (strict and value == 0.0):
        raise InvalidInput(f"must be a finite number {'>' if strict else '>='} 0", field=field, value=value)


def check_directions(directions: ArrayLike, field: str = "directions") -> FloatArray:
    """Validate pull directions (n, 3), n >= 1, non-zero and finite; return them normalised."""
    try:
        D = np.asarray(directions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("directions must be numbers", field=field) from exc
    if D.ndim == 1 and D.size == 3:
        D = D.reshape(1, 3)
    if D.ndim != 2 or D.shape[1] != 3 or D.shape[0] == 0:
        raise InvalidInput("expected a list of 3-vectors", field=field, value=list(D.shape))
    if not np.all(np.isfinite(D)):
        raise InvalidInput("NaN or infinite direction", field=field)
    norms = np.linalg.norm(D, axis=1)
    bad = np.flatnonzero(norms < 1e-12)
    if len(bad):
        raise InvalidInput("a direction is zero", field=f"{field}[{int(bad[0])}]", value=D[bad[0]].tolist())
    return np.asarray(D / norms[:, None])


def pull_test(
    grasp: Grasp,
    direction: ArrayLike,
    settings: PullSettings | None = None,
    *,
    work: mujoco.MjData | None = None,
) -> BreakForce:
    """Pull the grasped object along ``direction`` (hand frame) until it leaves the hand (module docstring).

    ``work`` is an optional scratch ``MjData`` of the grasp's model (overwritten). Raises :class:`SolverError` if
    the simulation diverges.
    """
    settings = settings or PullSettings()
    d_hand = check_directions(direction)[0]
    if not grasp.held:
        return BreakForce(d_hand, 0.0, False, "not_held", 0.0, 0.0)
    model = grasp.model
    data = work if work is not None else mujoco.MjData(model)
    mujoco.mj_copyData(data, model, grasp.data)
    pull = _Pull(grasp, d_hand, settings, data)
    if settings.mode == "ramp":
        return pull.ramp()
    return pull.quasi_static()


class _Pull:
    """One direction's pull test on a scratch ``MjData``."""

    def __init__(self, grasp: Grasp, d_hand: FloatArray, settings: PullSettings, data: mujoco.MjData) -> None:
        model = grasp.model
        self.grasp, self.model, self.data, self.settings, self.d_hand = grasp, model, data, settings, d_hand
        self.body, self.geom = grasp.object_body, grasp.object_geom
        self.hand_geom = np.array([model.geom_bodyid[g] not in (0, self.body) for g in range(model.ngeom)], dtype=bool)
        self.d_world = grasp.hand_rotation(data) @ d_hand
        self.c0 = data.xpos[self.body].copy()
        self.base = data.xfrc_applied[self.body, :3].copy()
        self.dt = float(model.opt.timestep)
        self.n_lost = max(1, round(settings.contact_loss_time / self.dt))
        self.vadr = grasp.object_dof
        self.sim_time = 0.0

    def _apply(self, force: float) -> None:
        self.data.xfrc_applied[self.body, :3] = self.base + force * self.d_world

    def _step(self) -> float:
        mujoco.mj_step(self.model, self.data)
        self.sim_time += self.dt
        disp = float(np.linalg.norm(self.data.xpos[self.body] - self.c0))
        if not math.isfinite(disp):
            raise SolverError("the pull-test simulation became unstable", field="direction", value=self.d_hand.tolist())
        return disp

    def ramp(self) -> BreakForce:
        s = self.settings
        n_ramp = math.ceil(s.cap / s.rate / self.dt - 1e-9)
        n_total = n_ramp + round(s.hold_at_cap / self.dt)
        lost, force_lost, disp = 0, 0.0, 0.0
        for k in range(1, n_total + 1):
            force = min(s.rate * k * self.dt, s.cap)
            self._apply(force)
            disp = self._step()
            if disp > s.displacement_threshold:
                return BreakForce(self.d_hand, force, False, "displacement", disp, self.sim_time)
            if _touching(self.data, self.geom, self.hand_geom):
                lost = 0
            else:
                if lost == 0:
                    force_lost = force
                lost += 1
                if lost >= self.n_lost:
                    return BreakForce(self.d_hand, force_lost, False, "contact_lost", disp, self.sim_time)
        return BreakForce(self.d_hand, s.cap, True, "cap", disp, self.sim_time)

    def _dwell(self, force: float) -> tuple[str | None, float]:
        """Hold ``force``: (None, displacement) if the object stays, else (reason, displacement)."""
        s = self.settings
        self._apply(force)
        n_min = round(s.min_dwell / self.dt)
        n_max = max(1, round(s.max_dwell / self.dt))
        lost, disp = 0, 0.0
        for k in range(1, n_max + 1):
            disp = self._step()
            if disp > s.displacement_threshold:
                return "displacement", disp
            if _touching(self.data, self.geom, self.hand_geom):
                lost = 0
            else:
                lost += 1
                if lost >= self.n_lost:
                    return "contact_lost", disp
            if k >= n_min and k % 5 == 0:
                v = self.data.qvel[self.vadr : self.vadr + 3]
                if float(np.linalg.norm(v)) < s.settle_speed:
                    break
        return None, disp

    def quasi_static(self) -> BreakForce:
        s = self.settings
        model = self.model
        held_state = mujoco.MjData(model)
        mujoco.mj_copyData(held_state, model, self.data)
        f_held, disp_held = 0.0, 0.0
        for level in s.levels():
            reason, disp = self._dwell(level)
            if reason is None:
                f_held, disp_held = level, disp
                mujoco.mj_copyData(held_state, model, self.data)
                continue
            f_break, reason_break, disp_break = level, reason, disp
            while f_break - f_held > max(s.resolution_abs, s.resolution_rel * f_break):
                mid = 0.5 * (f_held + f_break)
                mujoco.mj_copyData(self.data, model, held_state)
                reason, disp = self._dwell(mid)
                if reason is None:
                    f_held = mid
                    mujoco.mj_copyData(held_state, model, self.data)
                else:
                    f_break, reason_break, disp_break = mid, reason, disp
            return BreakForce(self.d_hand, f_break, False, cast(BreakReason, reason_break), disp_break, self.sim_time)
        return BreakForce(self.d_hand, s.cap, True, "cap", disp_held, self.sim_time)


def pull_tests(
    grasp: Grasp, directions: ArrayLike | None = None, settings: PullSettings | None = None
) -> tuple[BreakForce, ...]:
    """:func:`pull_test` for every direction (default :func:`default_directions`), in order."""
    D = default_directions() if directions is None else check_directions(directions)
    work = mujoco.MjData(grasp.model)
    return tuple(pull_test(grasp, d, settings, work=work) for d in D)


def _touching(data: mujoco.MjData, geom: int, hand_geom: NDArray[np.bool_]) -> bool:
    n = data.ncon
    if n == 0:
        return False
    g1 = np.asarray(data.contact.geom1[:n])
    g2 = np.asarray(data.contact.geom2[:n])
    active = np.asarray(data.contact.efc_address[:n]) >= 0
    return bool(np.any(active & (((g1 == geom) & hand_geom[g2]) | ((g2 == geom) & hand_geom[g1]))))


# ----------------------------------------------------------------------------------------------------------
# the stiffness signature
# ----------------------------------------------------------------------------------------------------------
