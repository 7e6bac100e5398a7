"""The capture model of a hand on an object: which relative poses of the object still end in a carried object.

**Coordinates** (hand frame of docs/design.md §3 seen from above; the hand in a top grasp, +z down):
``theta`` [rad] is the object's major axis o1 minus the hand's +x axis, as angles about world +z; ``u``, ``v`` [m]
are the object's centre minus the hand's placement point (docs/design.md §6), along the hand's +x and +y axes.
Strategy S is ``(0, 0, 0)``. The footprints of boxes, cylinders, spheres and ellipsoids are symmetric under a
half turn, so ``theta`` has period pi.

**The model** is a grid of MuJoCo grasp outcomes over (theta, u, v) (:mod:`softsig_service.simulation.capture`
builds it): ``values[i, j, k]`` is the fraction of simulated grasps at ``(theta[i], u[j], v[k])`` that carried the
object (0 or 1 with one simulation per cell). :meth:`CaptureModel.probability` interpolates it (trilinear,
periodic in theta, falling to 0 one step beyond the u, v edges): the capture probability of a relative pose.
:meth:`CaptureModel.expected` is that probability averaged over the pose noise of docs/design.md §7 (yaw
``N(0, sigma_r^2)`` [rad], shift ``N(0, sigma_t^2)`` [m] in x and y), by Gauss-Hermite quadrature: the smooth
objective of strategy R (:mod:`softsig_service.planning.strategy_r`).

Pure math: no simulation, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput

FloatArray = NDArray[np.float64]
THETA_PERIOD = math.pi
"""[rad] the footprints' symmetry: a half turn."""
QUADRATURE_NODES = 7
"""Gauss-Hermite nodes per noise dimension in :meth:`CaptureModel.expected`."""


def wrap_theta(theta: ArrayLike) -> FloatArray:
    """``theta`` [rad] wrapped into [-pi/2, pi/2)."""
    t = np.asarray(theta, dtype=np.float64)
    return np.asarray((t + THETA_PERIOD / 2) % THETA_PERIOD - THETA_PERIOD / 2, dtype=np.float64)


@dataclass(frozen=True)
class CaptureModel:
    """A grid of grasp outcomes over relative poses (module docstring).

    ``theta`` [rad] is uniform over one period starting at ``-pi/2``; ``u``, ``v`` [m] are increasing and
    uniform. ``values`` has shape ``(len(theta), len(u), len(v))``, entries in [0, 1]. ``meta`` records how it
    was built (hand, object, simulations, seconds, held-out accuracy).
    """

    theta: FloatArray
    u: FloatArray
    v: FloatArray
    values: FloatArray
    meta: dict[str, Any] = field(default_factory=dict)
    _padded: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        th, u, v = (np.asarray(a, dtype=np.float64).ravel() for a in (self.theta, self.u, self.v))
        vals = np.asarray(self.values, dtype=np.float64)
        if len(th) < 2 or len(u) < 2 or len(v) < 2:
            raise InvalidInput("each axis needs at least two values", field="grid")
        if vals.shape != (len(th), len(u), len(v)) or not np.all(np.isfinite(vals)):
            raise InvalidInput("values must be finite with shape (theta, u, v)", field="values", value=vals.shape)
        if np.any(vals < 0) or np.any(vals > 1):
            raise InvalidInput("values are fractions in [0, 1]", field="values")
        step = THETA_PERIOD / len(th)
        if not np.allclose(th, -THETA_PERIOD / 2 + step * np.arange(len(th)), atol=1e-9):
            raise InvalidInput("theta must be uniform over [-pi/2, pi/2)", field="theta")
        for name, a in (("u", u), ("v", v)):
            d = np.diff(a)
            if np.any(d <= 0) or not np.allclose(d, d[0], rtol=1e-6):
                raise InvalidInput("must be increasing and uniform", field=name)
        for name, a in (("theta", th), ("u", u), ("v", v), ("values", vals)):
            object.__setattr__(self, name, a)
        object.__setattr__(self, "_padded", np.pad(vals, ((0, 0), (1, 1), (1, 1))))

    # ---------------------------------------------------------------------------------------------------

    def probability(self, theta: ArrayLike, u: ArrayLike, v: ArrayLike) -> FloatArray:
        """Capture probability at relative poses (broadcast arrays; [rad], [m], [m])."""
        th = wrap_theta(theta)
        uu, vv = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
        th, uu, vv = np.broadcast_arrays(th, uu, vv)
        n_t = len(self.theta)
        ft = (th - self.theta[0]) / (THETA_PERIOD / n_t)
        i0 = np.floor(ft).astype(int)
        wt = ft - i0
        i0 %= n_t
        i1 = (i0 + 1) % n_t
        # u, v: pad one zero step on each side so that the probability falls to 0 beyond the grid
        out = np.zeros(th.shape)
        for ii, w_i in ((i0, 1.0 - wt), (i1, wt)):
            out += w_i * self._bilinear(ii, uu, vv)
        return np.clip(out, 0.0, 1.0)

    def _bilinear(self, ii: NDArray[np.int_], uu: FloatArray, vv: FloatArray) -> FloatArray:
        padded = self._padded
        du, dv = self.u[1] - self.u[0], self.v[1] - self.v[0]
        fu = np.clip((uu - self.u[0]) / du + 1.0, 0.0, len(self.u) + 1.0)
        fv = np.clip((vv - self.v[0]) / dv + 1.0, 0.0, len(self.v) + 1.0)
        j0 = np.minimum(np.floor(fu).astype(int), len(self.u))
        k0 = np.minimum(np.floor(fv).astype(int), len(self.v))
        wu, wv = fu - j0, fv - k0
        return np.asarray(
            (1 - wu) * (1 - wv) * padded[ii, j0, k0]
            + wu * (1 - wv) * padded[ii, j0 + 1, k0]
            + (1 - wu) * wv * padded[ii, j0, k0 + 1]
            + wu * wv * padded[ii, j0 + 1, k0 + 1],
            dtype=np.float64,
        )

    def expected(self, theta: ArrayLike, u: ArrayLike, v: ArrayLike, sigma_r: float, sigma_t: float) -> FloatArray:
        """The capture probability averaged over yaw noise ``N(0, sigma_r^2)`` [rad] and shifts
        ``N(0, sigma_t^2)`` [m] in x and y (isotropic, so the same along the hand's axes), by Gauss-Hermite
        quadrature (:data:`QUADRATURE_NODES` per noisy dimension)."""
        th, uu, vv = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (theta, u, v)))
        x, w = np.polynomial.hermite_e.hermegauss(QUADRATURE_NODES)
        w = w / w.sum()
        zero, one = np.zeros(1), np.ones(1)
        dt, wt = (sigma_r * x, w) if sigma_r > 0 else (zero, one)
        ds, ws = (sigma_t * x, w) if sigma_t > 0 else (zero, one)
        DT, DU, DV = np.meshgrid(dt, ds, ds, indexing="ij")
        W = (wt[:, None, None] * ws[None, :, None] * ws[None, None, :]).ravel()
        extra = (1,) * th.ndim
        p = self.probability(
            th[..., None] + DT.ravel().reshape((*extra, -1)),
            uu[..., None] + DU.ravel().reshape((*extra, -1)),
            vv[..., None] + DV.ravel().reshape((*extra, -1)),
        )
        return np.asarray(p @ W, dtype=np.float64)

    # ---------------------------------------------------------------------------------------------------

    def to_json_dict(self) -> dict[str, Any]:
        """JSON: the grid axes [rad, m, m], the values (theta-major nested lists) and ``meta``."""
        return {
            "theta": self.theta.tolist(),
            "u": self.u.tolist(),
            "v": self.v.tolist(),
            "values": self.values.tolist(),
            "meta": dict(self.meta),
        }

    @staticmethod
    def from_json_dict(d: Mapping[str, Any]) -> CaptureModel:
        """The model :meth:`to_json_dict` wrote; :class:`InvalidInput` for a malformed one."""
        try:
            return CaptureModel(
                theta=np.asarray(d["theta"], dtype=np.float64),
                u=np.asarray(d["u"], dtype=np.float64),
                v=np.asarray(d["v"], dtype=np.float64),
                values=np.asarray(d["values"], dtype=np.float64),
                meta=dict(d.get("meta") or {}),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidInput(f"not a capture model: {exc}", field="capture") from None


def uniform_axis(half_width: float, step: float) -> FloatArray:
    """``-half_width .. half_width`` [m] in steps of ``step`` [m] (symmetric about 0)."""
    n = round(half_width / step)
    return np.asarray(step * np.arange(-n, n + 1), dtype=np.float64)


def theta_axis(n: int) -> FloatArray:
    """``n`` uniform values of theta over [-pi/2, pi/2) [rad]."""
    return np.asarray(-THETA_PERIOD / 2 + THETA_PERIOD / n * np.arange(n), dtype=np.float64)


def agreement(model: CaptureModel, samples: Sequence[tuple[float, float, float, bool]]) -> float:
    """Fraction of held-out ``(theta, u, v, carried)`` samples whose outcome the model predicts
    (probability >= 0.5 means carried)."""
    if not samples:
        return float("nan")
    arr = np.asarray([s[:3] for s in samples], dtype=np.float64)
    pred = model.probability(arr[:, 0], arr[:, 1], arr[:, 2]) >= 0.5
    truth = np.asarray([bool(s[3]) for s in samples])
    return float(np.mean(pred == truth))
