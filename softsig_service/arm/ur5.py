"""The UR5 arm: Pinocchio model of example-robot-data's ``ur5_robot.urdf``, forward and inverse kinematics.

Frames and units:

* World frame = ``base_link`` of the URDF (z up; the URDF's ``world`` link coincides with it). Poses are 4x4
  homogeneous transforms ``T_world_frame`` with positions in [m].
* The flange frame is ``tool0`` (z out of the flange); a hand mounted on the arm has its frame = ``tool0``.
* Joint positions ``q`` are ``(6,)`` arrays in [rad], in the order of :data:`JOINT_NAMES`.

The model files are located at run time (:func:`~softsig_service.arm.robots_dir.find_robots_dir`).

Inverse kinematics (:meth:`UR5.solve_ik`) is a damped least-squares (Levenberg–Marquardt) iteration on the
SE(3) log error ``log6(T_fk^-1 T_target)`` with the frame Jacobian in the LOCAL frame, restarted from several
seeds; by default the seeds are the closed-form UR branches (:class:`~softsig_service.arm.ur_ik.URParameters`,
DH lengths read off the model and checked against it): an exact branch is accepted after one forward-kinematics
check, and the numeric iteration (:mod:`softsig_service.arm.numeric_ik`) runs only where no branch is exact. The
common call (a warm start, not exhaustive) is scalar Python throughout: the nearest branch found by a best-first
search over the closed form (:meth:`~softsig_service.arm.ur_ik.URParameters.nearest_branch`), one Pinocchio
forward kinematics to confirm it, no numpy on the way (within 2x of a compiled closed-form solver's time).
An unreachable target is a result with ``success=False`` and ``reason="unreachable"``, never an exception;
malformed input (NaN, wrong shape, not a rigid transform) raises :class:`~softsig_service.errors.InvalidInput`.

Thread safety: the model is shared and read-only; each thread gets its own ``pinocchio.Data``.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TypedDict

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray
from typing_extensions import Unpack

from softsig_service.arm.numeric_ik import levenberg_marquardt, settled
from softsig_service.arm.robots_dir import SRDF_RELATIVE, URDF_RELATIVE, find_robots_dir
from softsig_service.arm.ur_ik import URParameters, ur_parameters
from softsig_service.errors import FrameNotFound, InvalidInput
from softsig_service.geometry.checks import ORTHONORMAL_TOL, as_finite_array
from softsig_service.geometry.transforms import check_transform

FloatArray = NDArray[np.float64]

JOINT_NAMES: tuple[str, ...] = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
FLANGE_FRAME = "tool0"
BASE_FRAME = "base_link"

HOME_Q: tuple[float, ...] = (0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0)
"""A home configuration [rad]: elbow up, flange pointing down at (0.487, 0.109, 0.432) m. IK without a
``current_q`` returns the solution closest to it (at q = 0 the arm lies stretched out on the table)."""

POSITION_TOLERANCE = 1e-5
"""IK success threshold on the flange position error [m]."""
ROTATION_TOLERANCE = 1e-4
"""IK success threshold on the flange rotation error [rad] (angle of ``R_fk^T R_target``)."""


class IKOptions(TypedDict, total=False):
    """Options of :meth:`UR5.solve_ik`; every one may be left out (its default in parentheses).

    ``max_iterations`` (100): Levenberg–Marquardt iterations per seed; ``rng_seed`` (0): seed of the random
    restarts; ``exhaustive`` (False): run every seed of every group; ``analytic`` (True): try the closed-form
    branches first; ``position_tolerance`` [m] (:data:`POSITION_TOLERANCE`) and ``rotation_tolerance`` [rad]
    (:data:`ROTATION_TOLERANCE`): what counts as converged.
    """

    max_iterations: int
    rng_seed: int
    exhaustive: bool
    analytic: bool
    position_tolerance: float
    rotation_tolerance: float


_SOLUTION_DEDUP = 1e-4
"""Two IK solutions closer than this in every joint [rad] are the same solution."""
_FAST_ORTHONORMAL = 0.5 * ORTHONORMAL_TOL
"""A rotation this close to orthonormal with det 1 passes :func:`_checked_target` without numpy; one farther off
(or anything unusual) goes through :func:`~softsig_service.geometry.transforms.check_transform`, which decides."""


def _checked_target(target: ArrayLike) -> FloatArray:
    """``target`` as :func:`~softsig_service.geometry.transforms.check_transform` returns it (a rigid 4x4 float
    transform, [m]) or its :class:`InvalidInput`, field ``target``.

    A float64 4x4 array with the exact last row ``0 0 0 1``, a finite translation and a rotation within half of
    ``check_transform``'s tolerances is accepted by scalar arithmetic (so ``check_transform`` would accept it too,
    and return the same array); everything else is left to ``check_transform``.
    """
    if type(target) is np.ndarray and target.dtype == np.float64 and target.shape == (4, 4):
        (a, b, c, px), (d, e, f, py), (g, h, i, pz), last = target.tolist()
        tol = _FAST_ORTHONORMAL
        if (
            last == [0.0, 0.0, 0.0, 1.0]
            and math.isfinite(px + py + pz)
            and abs(a * a + d * d + g * g - 1.0) <= tol
            and abs(b * b + e * e + h * h - 1.0) <= tol
            and abs(c * c + f * f + i * i - 1.0) <= tol
            and abs(a * b + d * e + g * h) <= tol
            and abs(a * c + d * f + g * i) <= tol
            and abs(b * c + e * f + h * i) <= tol
            and abs(a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) - 1.0) <= tol
        ):
            return target
    return check_transform(target, field="target")


# ----------------------------------------------------------------------------------------------------------
# results
# ----------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class IKResult:
    """Outcome of :meth:`UR5.solve_ik`.

    Attributes:
        success: whether ``q`` reaches the target within the tolerances and the joint limits.
        q: joint positions ``(6,)`` [rad]: the chosen solution, or the best attempt when ``success`` is False.
        position_residual: flange position error ``|p_fk(q) - p_target|`` [m].
        rotation_residual: flange rotation error, angle of ``R_fk(q)^T R_target`` [rad].
        iterations: Levenberg–Marquardt iterations summed over every seed tried.
        seeds_tried: number of seeds started (``current_q`` counts as one).
        reason: ``None`` on success, ``"unreachable"`` otherwise.
        solutions: every distinct converged solution found (within limits), closest to the reference first.
    """

    success: bool
    q: FloatArray
    position_residual: float
    rotation_residual: float
    iterations: int
    seeds_tried: int
    reason: str | None
    solutions: tuple[FloatArray, ...] = field(default=(), repr=False)


# ----------------------------------------------------------------------------------------------------------
# the arm
# ----------------------------------------------------------------------------------------------------------


class UR5:
    """Pinocchio model of the UR5 (``ur5_robot.urdf`` of example-robot-data) with FK and numeric IK.

    Build it once with :func:`load_ur5` (cached). Attributes: ``model`` (``pinocchio.Model``), ``urdf_path``,
    ``srdf_path``, ``package_dir`` (the ``share`` folder for ``package://`` URIs), ``joint_names``,
    ``lower``/``upper`` joint limits [rad], ``velocity_limit`` [rad/s], ``effort_limit`` [N·m] and
    ``flange_frame_id``.
    """

    def __init__(self, robots_dir: Path | None = None) -> None:
        self.robots_dir = (robots_dir or find_robots_dir()).resolve()
        self.urdf_path = self.robots_dir / URDF_RELATIVE
        self.srdf_path = self.robots_dir / SRDF_RELATIVE
        # package://example-robot-data/robots/... resolves against <share>/example-robot-data/robots/...
        self.package_dir = self.robots_dir.parent.parent
        self.model: pin.Model = pin.buildModelFromUrdf(str(self.urdf_path))
        names = tuple(self.model.names[1:])
        if names != JOINT_NAMES:
            raise RuntimeError(f"unexpected UR5 joints {names}, expected {JOINT_NAMES}")
        self.joint_names = JOINT_NAMES
        self.nq = int(self.model.nq)
        self.lower: FloatArray = np.array(self.model.lowerPositionLimit, dtype=np.float64)
        self.upper: FloatArray = np.array(self.model.upperPositionLimit, dtype=np.float64)
        self.velocity_limit: FloatArray = np.array(self.model.velocityLimit, dtype=np.float64)
        self.effort_limit: FloatArray = np.array(self.model.effortLimit, dtype=np.float64)
        for arr in (self.lower, self.upper, self.velocity_limit, self.effort_limit):
            arr.setflags(write=False)
        self._lower_list: list[float] = self.lower.tolist()
        self._upper_list: list[float] = self.upper.tolist()
        if not self.model.existFrame(FLANGE_FRAME):
            raise RuntimeError(f"frame {FLANGE_FRAME!r} missing from {self.urdf_path}")
        self.flange_frame_id = int(self.model.getFrameId(FLANGE_FRAME))
        self.reach = self._reach_bound()
        self._reach_centre: list[float] = self.reach[0].tolist()
        self._local = threading.local()
        self.ur_parameters: URParameters | None = ur_parameters(self.model, self.data, self.flange_frame_id)
        """DH lengths for the closed-form seeds (None if the model is not a UR layout)."""

    # -- helpers ------------------------------------------------------------------------------------------

    @property
    def data(self) -> pin.Data:
        """This thread's ``pinocchio.Data`` (created on first use)."""
        d = getattr(self._local, "data", None)
        if d is None:
            d = self.model.createData()
            self._local.data = d
        return d

    def _reach_bound(self) -> tuple[FloatArray, float]:
        """A ball that contains every flange position: centre = the first joint's origin [m], radius [m].

        The first joint rotates about an axis through its origin, so no downstream point can be farther from
        it than the sum of the lengths of the later joint placements and of the flange offset.
        """
        centre = np.array(self.model.jointPlacements[1].translation)
        radius = sum(float(np.linalg.norm(self.model.jointPlacements[j].translation)) for j in range(2, 7))
        radius += float(np.linalg.norm(self.model.frames[self.flange_frame_id].placement.translation))
        return centre, radius

    def check_q(self, q: ArrayLike, field: str = "q") -> FloatArray:
        """``q`` as a finite ``(6,)`` float array [rad], or :class:`InvalidInput` naming ``field``."""
        # a float64 (6,) array with a finite sum has only finite entries: returned as as_finite_array would
        if type(q) is np.ndarray and q.dtype == np.float64 and q.shape == (self.nq,) and math.isfinite(sum(q.tolist())):
            return q
        return as_finite_array(q, (self.nq,), field)

    def within_limits(self, q: ArrayLike, tol: float = 1e-9) -> bool:
        """Whether every joint of ``q`` [rad] lies within its limits (widened by ``tol`` [rad])."""
        qa = self.check_q(q)
        return bool(np.all(qa >= self.lower - tol) and np.all(qa <= self.upper + tol))

    def wrap_to_limits(self, q: ArrayLike, reference: ArrayLike | None = None) -> FloatArray | None:
        """Shift each revolute joint by a multiple of 2 pi to the value within the limits closest to
        ``reference`` (default: zeros). Returns ``None`` if some joint has no such value.

        The joint-space distance to ``reference`` is then the real joint travel (angle wrapping considered).
        """
        qa = self.check_q(q)
        ref = np.zeros(self.nq) if reference is None else self.check_q(reference, "reference")
        wrapped, valid = self._wrap_rows(qa[None, :], ref)
        return wrapped[0] if valid[0] else None

    def _wrap_rows(self, Q: FloatArray, reference: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        """:meth:`wrap_to_limits` of every row of ``Q`` ``(k, 6)`` [rad], unchecked: (wrapped rows, which rows
        have a representative within the limits)."""
        two_pi = 2.0 * math.pi
        k_lo = np.ceil((self.lower - Q) / two_pi - 1e-12)
        k_hi = np.floor((self.upper - Q) / two_pi + 1e-12)
        valid = np.asarray((k_lo <= k_hi).all(axis=1))
        # |q + 2 pi k - ref| is convex in k (np.clip costs several times minimum/maximum on these small arrays)
        k = np.minimum(np.maximum(np.rint((reference - Q) / two_pi), k_lo), k_hi)
        return np.minimum(np.maximum(Q + k * two_pi, self.lower), self.upper), valid

    def random_configuration(self, rng: np.random.Generator) -> FloatArray:
        """A uniformly random configuration [rad] within the limits, restricted to [-pi, pi] per joint."""
        lo = np.maximum(self.lower, -math.pi)
        hi = np.minimum(self.upper, math.pi)
        return rng.uniform(lo, hi)

    # -- kinematics -----------------------------------------------------------------------------------------

    def frame_pose(self, q: ArrayLike, frame: str = FLANGE_FRAME) -> FloatArray:
        """Pose ``T_world_frame`` (4x4, [m]) of a model frame (link or joint name) at ``q`` [rad]."""
        qa = self.check_q(q)
        if not self.model.existFrame(frame):
            raise FrameNotFound(
                f"the UR5 model has no frame {frame!r}",
                field="frame",
                value=frame,
                choices=[f.name for f in self.model.frames],
            )
        fid = self.model.getFrameId(frame)
        d = self.data
        pin.forwardKinematics(self.model, d, qa)
        return np.array(pin.updateFramePlacement(self.model, d, fid).homogeneous)

    def fk(self, q: ArrayLike) -> FloatArray:
        """Flange pose ``T_world_tool0`` (4x4, [m]) at joint positions ``q`` [rad]."""
        return self._fk(self.check_q(q))

    def _fk(self, q: FloatArray) -> FloatArray:
        """:meth:`fk` of a checked ``(6,)`` float array [rad]."""
        d = self.data
        pin.forwardKinematics(self.model, d, q)
        return np.array(pin.updateFramePlacement(self.model, d, self.flange_frame_id).homogeneous)

    def jacobian(self, q: ArrayLike, local: bool = True) -> FloatArray:
        """Flange Jacobian ``(6, 6)`` (linear then angular) at ``q`` [rad].

        Expressed in the ``tool0`` frame (``local=True``) or in the world-aligned frame at the flange origin
        (``local=False``).
        """
        qa = self.check_q(q)
        ref = pin.ReferenceFrame.LOCAL if local else pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        return np.array(pin.computeFrameJacobian(self.model, self.data, qa, self.flange_frame_id, ref))

    @staticmethod
    def pose_error(T_a: ArrayLike, T_b: ArrayLike) -> tuple[float, float]:
        """Position error [m] and rotation angle [rad] between two 4x4 poses."""
        A = np.asarray(T_a, dtype=np.float64)
        B = np.asarray(T_b, dtype=np.float64)
        dp = float(np.linalg.norm(A[:3, 3] - B[:3, 3]))
        R = A[:3, :3].T @ B[:3, :3]
        c = 0.5 * (float(np.trace(R)) - 1.0)
        s = 0.5 * float(np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]))
        return dp, math.atan2(s, max(-1.0, min(1.0, c)))

    # -- inverse kinematics ----------------------------------------------------------------------------------

    def solve_ik(
        self,
        target: ArrayLike,
        current_q: ArrayLike | None = None,
        seeds: int = 8,
        *,
        extra_seeds: Sequence[ArrayLike] = (),
        **options: Unpack[IKOptions],
    ) -> IKResult:
        """Joint positions that put ``tool0`` at ``target`` (4x4 ``T_world_tool0``, [m]); ``options`` are the
        :class:`IKOptions` (defaults there).

        Every candidate is refined by the numeric solver: a Levenberg–Marquardt iteration on
        ``log6(T_fk^-1 T_target)`` with the LOCAL frame Jacobian (at most ``max_iterations`` per seed). Seeds
        come in groups, in this order:

        1. with ``analytic`` (and a UR layout, checked against the model at load time), the closed-form
           branches (up to 8, exact up to rounding), nearest to ``current_q`` first;
        2. ``current_q`` (if given), then ``extra_seeds``;
        3. ``seeds`` random configurations from ``numpy.random.default_rng(rng_seed)`` (same seed, same
           answer).

        A converged ``q`` is wrapped by multiples of 2 pi into the joint limits, choosing the representative
        closest to ``current_q`` (:data:`HOME_Q` if not given); it is rejected if none fits. Of all distinct solutions
        found, the one closest to ``current_q`` in joint space wins.

        Early stops (``exhaustive=False``): a group runs only if the groups before found nothing; the closed
        form stops at its first (nearest) branch that converges, so the answer is the arm's solution closest
        to ``current_q``; the ``current_q`` seed, when it converges, ends group 2 (the local solution); without
        ``current_q`` the random restarts stop at the first solution. When the closed form has no branch at
        all, the target is out of reach and the random restarts are skipped. ``exhaustive=True`` runs every
        seed of every group; ``exhaustive=True, seeds=0`` lists every closed-form branch (the arm's whole
        solution set, in ``IKResult.solutions``, nearest first) for about 1 ms, e.g. to try the next branch when
        the nearest collides. ``analytic=False`` gives the generic numeric solver alone (groups 2 and 3).

        Success needs position error <= ``position_tolerance`` [m] and rotation error <=
        ``rotation_tolerance`` [rad]. A target beyond the arm's reach, or one no seed converges to, gives
        ``success=False`` with ``reason="unreachable"`` and the best attempt in ``q``. Raises
        :class:`InvalidInput` for a malformed target or ``current_q``.
        """
        T = _checked_target(target)
        ref = None if current_q is None else self.check_q(current_q, "current_q")
        if seeds < 0 or options.get("max_iterations", 1) < 1:
            raise InvalidInput("seeds must be >= 0 and max_iterations >= 1", field="seeds", value=seeds)
        if not extra_seeds:
            return self.solve_ik_unchecked(T, ref, seeds, **options)
        extra = [self.check_q(x, f"extra_seeds[{i}]") for i, x in enumerate(extra_seeds)]
        return self.solve_ik_unchecked(T, ref, seeds, extra_seeds=extra, **options)

    def solve_ik_unchecked(
        self,
        T: FloatArray,
        current_q: FloatArray | None = None,
        seeds: int = 8,
        *,
        max_iterations: int = 100,
        rng_seed: int = 0,
        exhaustive: bool = False,
        analytic: bool = True,
        extra_seeds: Sequence[FloatArray] = (),
        position_tolerance: float = POSITION_TOLERANCE,
        rotation_tolerance: float = ROTATION_TOLERANCE,
    ) -> IKResult:
        """:meth:`solve_ik` for callers inside the service that pass already checked values: ``T`` a rigid 4x4
        float transform ``T_world_tool0`` [m], ``current_q`` and ``extra_seeds`` finite ``(6,)`` float arrays
        [rad], ``seeds >= 0``, ``max_iterations >= 1``. Nothing is validated again.

        The common call (``analytic``, not ``exhaustive``) first takes the closed-form branch nearest the
        reference (:meth:`~softsig_service.arm.ur_ik.URParameters.nearest_branch`: the one the seed loop would
        try first) and returns it after one forward kinematics when it is exact to within 1e-3 of the tolerances
        (:func:`~softsig_service.arm.numeric_ik.settled`: what the seed loop would accept after 0 iterations);
        anything else (no branch within the limits, a branch that is not exact, e.g. near a singularity) goes
        through the seed loop below, as before."""
        rows = T.tolist()
        reference = np.array(HOME_Q) if current_q is None else current_q
        if math.dist((rows[0][3], rows[1][3], rows[2][3]), self._reach_centre) > self.reach[1] + 1e-6:
            q_best = reference.copy()
            pe, re = self.pose_error(self._fk(q_best), T)
            return IKResult(False, q_best, pe, re, 0, 0, "unreachable")
        M = pin.SE3(T)
        params = self.ur_parameters
        if analytic and params is not None and not exhaustive:
            # the nearest closed-form branch, accepted after one forward kinematics when it is exact
            near = params.nearest_branch(rows, reference.tolist(), self._lower_list, self._upper_list)
            if near is not None:
                q_near = np.array(near)
                exact = settled(
                    self.model, self.data, self.flange_frame_id, M, q_near, position_tolerance, rotation_tolerance
                )
                if exact is not None:
                    return IKResult(True, q_near, exact[0], exact[1], 0, 1, None, (q_near,))

        solutions: list[tuple[float, FloatArray, float, float]] = []
        best_fail: list[tuple[float, FloatArray, float, float]] = []
        counters = [0, 0]  # seeds tried, iterations
        model, fid = self.model, self.flange_frame_id

        def run(q0: FloatArray, prewrapped: bool = False) -> bool:
            """Refine one seed; record the solution (True) or the failure. A ``prewrapped`` seed is already the
            representative within the limits closest to the reference (wrapping it again changes nothing)."""
            counters[0] += 1
            q, pe, re, it, ok = levenberg_marquardt(
                model, self.data, fid, M, q0, max_iterations, position_tolerance, rotation_tolerance
            )
            counters[1] += it
            if ok:
                if it == 0 and prewrapped:
                    qw, valid = q, True  # an exact closed-form branch: checked once, by the step above
                else:
                    wrapped, valid_rows = self._wrap_rows(q[None, :], reference)
                    qw, valid = wrapped[0], bool(valid_rows[0])
                    if valid and (it > 0 or not np.array_equal(qw, q)):
                        pe, re = self.pose_error(self._fk(qw), T)
                if valid and pe <= position_tolerance and re <= rotation_tolerance:
                    if not any(np.max(np.abs(qw - x[1])) < _SOLUTION_DEDUP for x in solutions):
                        d = qw - reference
                        solutions.append((math.sqrt(d @ d), qw, pe, re))
                    return True
            score = pe + 0.1 * re
            if not best_fail or score < best_fail[0][0]:
                best_fail[:] = [(score, q, pe, re)]
            return False

        # 1. the closed-form branches, nearest to current_q first (exact: one forward-kinematics check each)
        out_of_reach = False
        if analytic and self.ur_parameters is not None:
            branches = self.ur_parameters.ik_array(T, q6_default=float(reference[5]))
            out_of_reach = len(branches) == 0
            wrapped, valid = self._wrap_rows(branches, reference)
            wrapped = wrapped[valid]
            d = wrapped - reference
            # (not exhaustive, the shortcut above found the nearest branch not exact: run() polishes it, then the next)
            order = np.argsort(np.sqrt((d * d).sum(axis=1)), kind="stable").tolist()
            for i in order:
                if run(wrapped[i], prewrapped=True) and not exhaustive:
                    break
        # 2. current_q, then the caller's extra seeds
        if exhaustive or not solutions:
            given: list[FloatArray] = [] if current_q is None else [current_q]
            given.extend(extra_seeds)
            for i, q0 in enumerate(given):
                if run(q0) and i == 0 and current_q is not None and not exhaustive:
                    break
        # 3. random restarts, when nothing was found (or always when exhaustive)
        if exhaustive or (not solutions and not out_of_reach):
            rng = np.random.default_rng(rng_seed)
            for _ in range(seeds):
                if run(self.random_configuration(rng)) and current_q is None and not exhaustive:
                    break
        total_it, tried = counters[1], counters[0]

        if solutions:
            solutions.sort(key=lambda x: x[0])
            _, q_sol, pe, re = solutions[0]
            return IKResult(True, q_sol, pe, re, total_it, tried, None, tuple(x[1] for x in solutions))
        if not best_fail:  # no seed at all
            q_none = reference.copy()
            pe, re = self.pose_error(self._fk(q_none), T)
            return IKResult(False, q_none, pe, re, total_it, tried, "unreachable")
        _, q_bad, pe, re = best_fail[0]
        bad_w, bad_valid = self._wrap_rows(q_bad[None, :], reference)
        return IKResult(False, bad_w[0] if bad_valid[0] else q_bad, pe, re, total_it, tried, "unreachable")


@lru_cache(maxsize=4)
def load_ur5(robots_dir: Path | None = None) -> UR5:
    """The process-wide UR5 model of ``robots_dir`` (default: the installed example-robot-data), built once and
    cached."""
    return UR5(robots_dir)
