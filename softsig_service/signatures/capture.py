"""The capture model of a hand on an object: which relative poses of the object still end in a carried object.

**Coordinates** (hand frame of docs/design.md §3 seen from above; the hand in a top grasp, +z down):
``theta`` [rad] is the object's major axis o1 minus the hand's +x axis, as angles about world +z; ``u``, ``v`` [m]
are the object's centre minus the hand's placement point (docs/design.md §6), along the hand's +x and +y axes.
Strategy S is ``(0, 0, 0)``. The footprints of boxes, cylinders, spheres and ellipsoids are symmetric under a
half turn, so ``theta`` has period pi.

**The model** is a grid of MuJoCo grasp outcomes over (theta, u, v) (:mod:`softsig_service.experiments.capture`
builds it): ``values[i, j, k]`` is the fraction of simulated grasps at ``(theta[i], u[j], v[k])`` that carried the
object (0 or 1 with one simulation per cell). :meth:`CaptureModel.probability` interpolates it (trilinear,
periodic in theta, falling to 0 one step beyond the u, v edges): the capture probability of a relative pose.
:meth:`CaptureModel.expected` is that probability averaged over the pose noise of docs/design.md §7 (yaw
``N(0, sigma_r^2)`` [rad], shift ``N(0, sigma_t^2)`` [m] in x and y), by Gaussian convolution on a finer grid:
the smooth objective of strategy R (:mod:`softsig_service.planning.strategy_r`).

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
REFINE = 4
"""The noise-averaged model (:meth:`CaptureModel.blurred`) is sampled at least this many times finer."""


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
    _blur: dict[tuple[float, float], CaptureModel] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        th, u, v = (np.asarray(a, dtype=np.float64).ravel() for a in (self.theta, self.u, self.v))
        vals = np.asarray(self.values, dtype=np.float64)
        if len(th) < 2 or len(u) < 2 or len(v) < 2:
            raise InvalidInput("each axis needs at least two values", field="grid")
        if vals.shape != (len(th), len(u), len(v)) or not np.all(np.isfinite(vals)):
            raise InvalidInput("values must be finite with shape (theta, u, v)", field="values", value=vals.shape)
        if np.any(vals < 0) or np.any(vals > 1):
            raise InvalidInput("values are fractions in [0, 1]", field="values")
        if not np.allclose(th, theta_axis(len(th)), atol=1e-9):
            raise InvalidInput("theta must be uniform over [-pi/2, pi/2)", field="theta")
        for name, a in (("u", u), ("v", v)):
            d = np.diff(a)
            if np.any(d <= 0) or not np.allclose(d, d[0], rtol=1e-6):
                raise InvalidInput("must be increasing and uniform", field=name)
        for name, a in (("theta", th), ("u", u), ("v", v), ("values", vals)):
            object.__setattr__(self, name, a)
        object.__setattr__(self, "_padded", np.pad(vals, ((0, 0), (1, 1), (1, 1))))
        object.__setattr__(self, "_blur", {})

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
        ``N(0, sigma_t^2)`` [m] in x and y (isotropic, so the same along the hand's axes): the interpolated
        :meth:`blurred` model."""
        return self.blurred(sigma_r, sigma_t).probability(theta, u, v)

    def blurred(self, sigma_r: float, sigma_t: float) -> CaptureModel:
        """The model's interpolant convolved with the pose noise, on a finer grid (cached per sigmas).

        The interpolant is sampled on a grid at most ``sigma / 2`` apart (and at least :data:`REFINE` times finer
        than the model's), extended beyond the u, v edges by the kernel's reach (``4 sigma_t`` plus one step,
        where it is 0), and convolved axis by axis with sampled Gaussians (``scipy.ndimage.gaussian_filter1d``:
        periodic in theta, zero beyond the u, v edges). With both sigmas 0 it is the model itself."""
        key = (float(sigma_r), float(sigma_t))
        cached = self._blur.get(key)
        if cached is not None:
            return cached
        if sigma_r <= 0 and sigma_t <= 0:
            self._blur[key] = self
            return self
        from scipy.ndimage import gaussian_filter1d

        d_theta = THETA_PERIOD / len(self.theta)
        n_t = len(self.theta) * max(REFINE, math.ceil(2 * d_theta / sigma_r) if sigma_r > 0 else REFINE)
        th = theta_axis(n_t)

        def fine(axis: FloatArray) -> FloatArray:
            step = float(axis[1] - axis[0])
            k = max(REFINE, math.ceil(2 * step / sigma_t) if sigma_t > 0 else REFINE)
            reach = step + 4.0 * sigma_t
            n_out = math.ceil(reach / (step / k))
            return np.asarray(axis[0] + step / k * np.arange(-n_out, (len(axis) - 1) * k + n_out + 1))

        uu, vv = fine(self.u), fine(self.v)
        T, U, V = np.meshgrid(th, uu, vv, indexing="ij")
        values = self.probability(T, U, V)
        if sigma_r > 0:
            values = gaussian_filter1d(values, sigma_r / (th[1] - th[0]), axis=0, mode="wrap", truncate=4.0)
        if sigma_t > 0:
            values = gaussian_filter1d(values, sigma_t / (uu[1] - uu[0]), axis=1, mode="constant", truncate=4.0)
            values = gaussian_filter1d(values, sigma_t / (vv[1] - vv[0]), axis=2, mode="constant", truncate=4.0)
        out = CaptureModel(th, uu, vv, np.clip(values, 0.0, 1.0), {"blurred": {"sigma_r": key[0], "sigma_t": key[1]}})
        self._blur[key] = out
        return out

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


MIN_CAPTURE_STEP = 1e-4
"""[m] the finest offset step of a capture grid: 0.1 mm, the UR5's stated pose repeatability (+-0.1 mm, Universal
Robots' UR5 technical specifications); a finer grid resolves nothing the arm can place."""


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
