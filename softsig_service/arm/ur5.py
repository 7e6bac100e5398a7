"""The UR5 arm: Pinocchio model of example-robot-data's ``ur5_robot.urdf``, forward and inverse kinematics.

Frames and units:

* World frame = ``base_link`` of the URDF (z up; the URDF's ``world`` link coincides with it). Poses are 4x4
  homogeneous transforms ``T_world_frame`` with positions in [m].
* The flange frame is ``tool0`` (z out of the flange); a hand mounted on the arm has its frame = ``tool0``.
* Joint positions ``q`` are ``(6,)`` arrays in [rad], in the order of :data:`JOINT_NAMES`.

The model files are never copied: they are located at run time in the installed example-robot-data package
(``cmeel.prefix/share/example-robot-data/robots``), or in a folder the caller names (the ``robots`` folder that
holds ``ur_description``; the service's setting ``robots_dir``, ``SOFTSIG_ROBOTS_DIR``). See :func:`find_robots_dir`.

Inverse kinematics (:meth:`UR5.solve_ik`) is a damped least-squares (Levenberg–Marquardt) iteration on the
SE(3) log error ``log6(T_fk^-1 T_target)`` with the frame Jacobian in the LOCAL frame, restarted from several
seeds; by default the seeds are the closed-form UR branches (:class:`URParameters`, DH lengths read off the
model and checked against it), so the numeric step only confirms an exact solution. An unreachable target is a
result with ``success=False`` and ``reason="unreachable"``, never an exception; malformed input (NaN, wrong
shape, not a rigid transform) raises :class:`~softsig_service.errors.InvalidInput`.

Thread safety: the model is shared and read-only; each thread gets its own ``pinocchio.Data``.
"""

from __future__ import annotations

import contextlib
import math
import os
import site
import sys
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import FrameNotFound, InvalidInput
from softsig_service.geometry.checks import as_finite_array
from softsig_service.geometry.transforms import check_transform

FloatArray = NDArray[np.float64]

"""Environment variable naming the example-robot-data ``robots`` folder (overrides the search)."""

URDF_RELATIVE = Path("ur_description/urdf/ur5_robot.urdf")
SRDF_RELATIVE = Path("ur_description/srdf/ur5.srdf")

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

_SOLUTION_DEDUP = 1e-4
"""Two IK solutions closer than this in every joint [rad] are the same solution."""


# ----------------------------------------------------------------------------------------------------------
# locating the model files
# ----------------------------------------------------------------------------------------------------------


def _candidate_roots() -> Iterator[Path]:
    """Folders that may hold ``cmeel.prefix`` (site-packages of this interpreter, then ``sys.path``)."""
    seen: set[Path] = set()
    roots: list[str] = []
    try:
        import cmeel  # the pip wheels install into <site-packages>/cmeel.prefix

        roots.append(str(Path(cmeel.__file__).resolve().parent.parent))
    except ImportError:  # pragma: no cover - cmeel ships with pin
        pass
    with contextlib.suppress(AttributeError):  # some virtualenv flavours lack it
        roots.extend(site.getsitepackages())
    roots.append(site.getusersitepackages())
    roots.extend(sys.path)
    pyver = f"python{sys.version_info.major}.{sys.version_info.minor}"
    for prefix in (sys.prefix, sys.base_prefix):
        roots.append(os.path.join(prefix, "lib", pyver, "site-packages"))
    for r in roots:
        if not r:
            continue
        p = Path(r).resolve()
        if p not in seen:
            seen.add(p)
            yield p


def find_robots_dir(override: Path | None = None) -> Path:
    """The example-robot-data ``robots`` folder (the one that holds ``ur_description``).

    ``override`` wins when given (and must hold ``ur_description/urdf/ur5_robot.urdf``); otherwise
    ``cmeel.prefix/share/example-robot-data/robots`` is looked up under the site-packages of this interpreter
    and the entries of ``sys.path``. Raises ``FileNotFoundError`` listing what was searched.
    """
    if override is not None:
        p = Path(override).expanduser().resolve()
        if not (p / URDF_RELATIVE).is_file():
            raise FileNotFoundError(f"robots_dir={str(override)!r} does not contain {URDF_RELATIVE}")
        return p
    searched: list[str] = []
    for root in _candidate_roots():
        p = root / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        searched.append(str(p))
        if (p / URDF_RELATIVE).is_file():
            return p
    raise FileNotFoundError(
        "example-robot-data's robots folder was not found (install the 'example-robot-data' package or set "
        f"SOFTSIG_ROBOTS_DIR); searched: {', '.join(searched)}"
    )


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
# closed-form UR inverse kinematics (seeds for the numeric solver)
# ----------------------------------------------------------------------------------------------------------

_DH_ALPHA = (math.pi / 2.0, 0.0, 0.0, math.pi / 2.0, -math.pi / 2.0, 0.0)
_RZ_PI = np.diag([-1.0, -1.0, 1.0, 1.0])
"""``base_link`` is the DH base frame turned by pi about z (the URDF's note on ``base``)."""


@dataclass(frozen=True)
class URParameters:
    """Standard DH lengths [m] of a UR arm: ``a = (0, -a2, -a3, 0, 0, 0)``, ``d = (d1, 0, 0, d4, d5, d6)``,
    ``alpha = (pi/2, 0, 0, pi/2, -pi/2, 0)``. ``T_base_link_tool0(q) = Rz(pi) T_dh(q)``."""

    d1: float
    a2: float
    a3: float
    d4: float
    d5: float
    d6: float

    def fk(self, q: ArrayLike) -> FloatArray:
        """``T_base_link_tool0`` (4x4, [m]) from the DH table at ``q`` [rad]."""
        a = (0.0, -self.a2, -self.a3, 0.0, 0.0, 0.0)
        d = (self.d1, 0.0, 0.0, self.d4, self.d5, self.d6)
        T = _RZ_PI.copy()
        for i, th in enumerate(np.asarray(q, dtype=np.float64)):
            T = T @ _dh_matrix(float(th), d[i], a[i], _DH_ALPHA[i])
        return T

    def ik(self, target: FloatArray, q6_default: float = 0.0) -> list[FloatArray]:
        """Up to 8 closed-form solutions [rad] (in (-pi, pi]) for ``T_base_link_tool0 = target``.

        Branches whose trigonometric arguments leave [-1, 1] by more than 1e-6 are dropped; arguments just
        outside are clamped (the numeric solver polishes the result). At the wrist singularity (sin q5 ~ 0)
        q6 is free and set to ``q6_default``.
        """
        T = _RZ_PI @ target  # Rz(pi) is its own inverse
        R, p = T[:3, :3], T[:3, 3]
        p05 = p - self.d6 * R[:, 2]
        r = math.hypot(p05[0], p05[1])
        if r < 1e-12:
            return []
        c = self.d4 / r
        if abs(c) > 1.0 + 1e-6:
            return []
        phi = math.acos(max(-1.0, min(1.0, c)))
        psi = math.atan2(p05[1], p05[0])
        out: list[FloatArray] = []
        for q1 in (psi + phi + math.pi / 2.0, psi - phi + math.pi / 2.0):
            s1, c1 = math.sin(q1), math.cos(q1)
            c5 = (p[0] * s1 - p[1] * c1 - self.d4) / self.d6
            if abs(c5) > 1.0 + 1e-6:
                continue
            a5 = math.acos(max(-1.0, min(1.0, c5)))
            for q5 in (a5, -a5):
                s5 = math.sin(q5)
                if abs(s5) < 1e-10:
                    q6 = q6_default
                else:
                    q6 = math.atan2((-R[0, 1] * s1 + R[1, 1] * c1) / s5, (R[0, 0] * s1 - R[1, 0] * c1) / s5)
                T01 = _dh_matrix(q1, self.d1, 0.0, _DH_ALPHA[0])
                T45 = _dh_matrix(q5, self.d5, 0.0, _DH_ALPHA[4])
                T56 = _dh_matrix(q6, self.d6, 0.0, _DH_ALPHA[5])
                T14 = _inv(T01) @ T @ _inv(T56) @ _inv(T45)
                x, y = T14[0, 3], T14[1, 3]  # frame-3 origin in frame 1 (planar 2-link)
                L2, L3 = -self.a2, -self.a3
                c3 = (x * x + y * y - L2 * L2 - L3 * L3) / (2.0 * L2 * L3)
                if abs(c3) > 1.0 + 1e-6:
                    continue
                a3 = math.acos(max(-1.0, min(1.0, c3)))
                for q3 in (a3, -a3):
                    q2 = math.atan2(y, x) - math.atan2(L3 * math.sin(q3), L2 + L3 * math.cos(q3))
                    q234 = math.atan2(T14[1, 0], T14[0, 0])
                    q4 = q234 - q2 - q3
                    sol = np.array([q1, q2, q3, q4, q5, q6])
                    out.append(np.remainder(sol + math.pi, 2.0 * math.pi) - math.pi)
        return out


def _dh_matrix(theta: float, d: float, a: float, alpha: float) -> FloatArray:
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _inv(T: FloatArray) -> FloatArray:
    out = np.eye(4)
    out[:3, :3] = T[:3, :3].T
    out[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return out


def _ur_parameters(model: pin.Model, data: pin.Data, flange_frame_id: int) -> URParameters | None:
    """DH lengths read off the model at q = 0 and checked against Pinocchio's FK; None if they disagree
    (then only the numeric solver is used)."""
    q0 = np.zeros(model.nq)
    pin.forwardKinematics(model, data, q0)
    o = [np.array(data.oMi[j].translation) for j in range(model.njoints)]
    tool = np.array(pin.updateFramePlacement(model, data, flange_frame_id).translation)
    params = URParameters(
        d1=float(o[1][2]),
        a2=float(abs(o[3][0] - o[2][0])),
        a3=float(abs(o[4][0] - o[3][0])),
        d4=float(o[5][1]),
        d5=float(o[5][2] - o[6][2]),
        d6=float(tool[1] - o[6][1]),
    )
    rng = np.random.default_rng(1234)
    for _ in range(10):
        q = rng.uniform(-math.pi, math.pi, model.nq)
        pin.forwardKinematics(model, data, q)
        T = np.array(pin.updateFramePlacement(model, data, flange_frame_id).homogeneous)
        if not np.allclose(params.fk(q), T, atol=1e-9):
            return None
    return params


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
        if not self.model.existFrame(FLANGE_FRAME):
            raise RuntimeError(f"frame {FLANGE_FRAME!r} missing from {self.urdf_path}")
        self.flange_frame_id = int(self.model.getFrameId(FLANGE_FRAME))
        self.reach = self._reach_bound()
        self._local = threading.local()
        self.ur_parameters: URParameters | None = _ur_parameters(self.model, self.data, self.flange_frame_id)
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
        two_pi = 2.0 * math.pi
        k_lo = np.ceil((self.lower - qa) / two_pi - 1e-12)
        k_hi = np.floor((self.upper - qa) / two_pi + 1e-12)
        if np.any(k_lo > k_hi):
            return None
        k = np.clip(np.round((ref - qa) / two_pi), k_lo, k_hi)  # |q + 2 pi k - ref| is convex in k
        return np.clip(qa + k * two_pi, self.lower, self.upper)

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
        qa = self.check_q(q)
        d = self.data
        pin.forwardKinematics(self.model, d, qa)
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

    def _lm(
        self,
        target: pin.SE3,
        q0: FloatArray,
        max_iterations: int,
        tol_p: float,
        tol_r: float,
    ) -> tuple[FloatArray, float, float, int, bool]:
        """One damped least-squares run from ``q0``.

        Returns (q, position error [m], rotation error [rad], iterations, converged).
        """
        model, d, fid = self.model, self.data, self.flange_frame_id
        q = q0.copy()

        def error(qq: FloatArray) -> tuple[pin.SE3, FloatArray, float, float, float]:
            pin.forwardKinematics(model, d, qq)
            iMd = pin.updateFramePlacement(model, d, fid).actInv(target)
            e = np.asarray(pin.log6(iMd).vector)
            pe = float(np.linalg.norm(iMd.translation))
            re = float(np.linalg.norm(e[3:]))
            return iMd, e, pe, re, float(e @ e)

        iMd, e, pe, re, cost = error(q)
        lam = 1e-3
        eye = np.eye(6)
        it = 0
        polish = 2  # once within tolerance, up to two more Newton steps towards 1e-3 of it
        while it < max_iterations:
            if pe <= tol_p and re <= tol_r:
                if polish == 0 or (pe <= 1e-3 * tol_p and re <= 1e-3 * tol_r):
                    return q, pe, re, it, True
                polish -= 1
            it += 1
            # J is d(log6(T_fk^-1 T_target))/dq; computeFrameJacobian also refreshes the kinematics at q.
            J = pin.computeFrameJacobian(model, d, q, fid, pin.ReferenceFrame.LOCAL)
            Je = -pin.Jlog6(iMd.inverse()) @ J
            JtJ = Je.T @ Je
            g = Je.T @ e
            accepted = False
            improvement = 0.0
            while lam < 1e8:
                dq = -np.linalg.solve(JtJ + lam * (eye + np.diag(np.diag(JtJ))), g)
                q_new = q + dq
                iMd_n, e_n, pe_n, re_n, cost_n = error(q_new)
                if cost_n < cost:
                    q, iMd, e, pe, re = q_new, iMd_n, e_n, pe_n, re_n
                    lam = max(lam / 10.0, 1e-9)
                    accepted = True
                    improvement = cost - cost_n
                    cost = cost_n
                    break
                lam *= 10.0
            if not accepted:
                break  # local minimum: no damped step lowers the error
            if improvement < 1e-14 * max(cost, 1e-30) and float(np.linalg.norm(dq)) < 1e-12:
                break
        ok = pe <= tol_p and re <= tol_r
        return q, pe, re, it, ok

    def solve_ik(
        self,
        target: ArrayLike,
        current_q: ArrayLike | None = None,
        seeds: int = 8,
        *,
        max_iterations: int = 100,
        rng_seed: int = 0,
        exhaustive: bool = False,
        analytic: bool = True,
        extra_seeds: Sequence[ArrayLike] = (),
        position_tolerance: float = POSITION_TOLERANCE,
        rotation_tolerance: float = ROTATION_TOLERANCE,
    ) -> IKResult:
        """Joint positions that put ``tool0`` at ``target`` (4x4 ``T_world_tool0``, [m]).

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
        T = check_transform(target, field="target")
        ref = None if current_q is None else self.check_q(current_q, "current_q")
        if seeds < 0 or max_iterations < 1:
            raise InvalidInput("seeds must be >= 0 and max_iterations >= 1", field="seeds", value=seeds)
        M = pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())
        reference = np.array(HOME_Q) if ref is None else ref

        centre, radius = self.reach
        if float(np.linalg.norm(T[:3, 3] - centre)) > radius + 1e-6:
            q_best = reference.copy()
            pe, re = self.pose_error(self.fk(q_best), T)
            return IKResult(False, q_best, pe, re, 0, 0, "unreachable")

        solutions: list[tuple[float, FloatArray, float, float]] = []
        best_fail: list[tuple[float, FloatArray, float, float]] = []
        counters = [0, 0]  # seeds tried, iterations

        def run(q0: FloatArray) -> bool:
            """Refine one seed; record the solution (True) or the failure."""
            counters[0] += 1
            q, pe, re, it, ok = self._lm(M, q0, max_iterations, position_tolerance, rotation_tolerance)
            counters[1] += it
            qw = self.wrap_to_limits(q, reference) if ok else None
            if qw is not None:
                pe, re = self.pose_error(self.fk(qw), T)
                if pe <= position_tolerance and re <= rotation_tolerance:
                    if not any(np.max(np.abs(qw - x[1])) < _SOLUTION_DEDUP for x in solutions):
                        solutions.append((float(np.linalg.norm(qw - reference)), qw, pe, re))
                    return True
            score = pe + 0.1 * re
            if not best_fail or score < best_fail[0][0]:
                best_fail[:] = [(score, q, pe, re)]
            return False

        # 1. the closed-form branches, nearest to current_q first (exact: the numeric step only confirms them)
        out_of_reach = False
        if analytic and self.ur_parameters is not None:
            branches = self.ur_parameters.ik(T, q6_default=float(reference[5]))
            out_of_reach = not branches
            wrapped = [w for b in branches if (w := self.wrap_to_limits(b, reference)) is not None]
            for _, _, w in sorted((float(np.linalg.norm(w - reference)), i, w) for i, w in enumerate(wrapped)):
                if run(w) and not exhaustive:
                    break
        # 2. current_q, then the caller's extra seeds
        if exhaustive or not solutions:
            given: list[FloatArray] = [] if ref is None else [ref]
            given.extend(self.check_q(x, f"extra_seeds[{i}]") for i, x in enumerate(extra_seeds))
            for i, q0 in enumerate(given):
                if run(q0) and i == 0 and ref is not None and not exhaustive:
                    break
        # 3. random restarts, when nothing was found (or always when exhaustive)
        if exhaustive or (not solutions and not out_of_reach):
            rng = np.random.default_rng(rng_seed)
            for _ in range(seeds):
                if run(self.random_configuration(rng)) and ref is None and not exhaustive:
                    break
        total_it, tried = counters[1], counters[0]

        if solutions:
            solutions.sort(key=lambda x: x[0])
            _, q_sol, pe, re = solutions[0]
            return IKResult(True, q_sol, pe, re, total_it, tried, None, tuple(x[1] for x in solutions))
        if not best_fail:  # no seed at all
            q_none = reference.copy()
            pe, re = self.pose_error(self.fk(q_none), T)
            return IKResult(False, q_none, pe, re, total_it, tried, "unreachable")
        _, q_bad, pe, re = best_fail[0]
        q_bad_w = self.wrap_to_limits(q_bad, reference)
        return IKResult(False, q_bad if q_bad_w is None else q_bad_w, pe, re, total_it, tried, "unreachable")


@lru_cache(maxsize=4)
def load_ur5(robots_dir: Path | None = None) -> UR5:
    """The process-wide UR5 model of ``robots_dir`` (default: the installed example-robot-data), built once and
    cached."""
    return UR5(robots_dir)
