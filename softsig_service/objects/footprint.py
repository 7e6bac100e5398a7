"""Footprint geometry of objects on the table: the 2D convex hull and the polygon's second moments of area.

Pure numpy; lengths in [m] in whatever planar frame the caller uses (softsig: the object frame's xy plane).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput

FloatArray = NDArray[np.float64]


def convex_hull_2d(points: ArrayLike) -> FloatArray:
    """Convex hull (counter-clockwise, no repeated end point) of 2D points ``(N, 2)`` (monotone chain)."""
    P = np.unique(np.asarray(points, dtype=np.float64), axis=0)
    if len(P) < 3:
        return P
    pts = sorted(map(tuple, P))

    def cross(o: tuple[float, ...], a: tuple[float, ...], b: tuple[float, ...]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, ...]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0.0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, ...]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0.0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def polygon_moments(poly: ArrayLike) -> tuple[float, FloatArray, FloatArray]:
    """Area [m^2], centroid ``(2,)`` [m] and central second-moment matrix ``(2, 2)`` [m^4] of a simple polygon
    given counter-clockwise (Green's theorem)."""
    P = np.asarray(poly, dtype=np.float64)
    x, y = P[:, 0], P[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    c = x * yn - xn * y
    area = 0.5 * float(c.sum())
    if abs(area) < 1e-18:
        raise InvalidInput("the footprint has no area", field="footprint")
    cx = float(((x + xn) * c).sum()) / (6.0 * area)
    cy = float(((y + yn) * c).sum()) / (6.0 * area)
    ixx = float(((x * x + x * xn + xn * xn) * c).sum()) / 12.0  # integral of x^2 dA
    iyy = float(((y * y + y * yn + yn * yn) * c).sum()) / 12.0
    ixy = float(((x * yn + 2.0 * x * y + 2.0 * xn * yn + xn * y) * c).sum()) / 24.0
    M = np.array([[ixx - area * cx * cx, ixy - area * cx * cy], [ixy - area * cx * cy, iyy - area * cy * cy]])
    return area, np.array([cx, cy]), M
