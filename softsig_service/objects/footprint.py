"""Footprint geometry of objects on the table: the 2D convex hull (qhull) and the polygon's second moments of area.

Lengths in [m] in whatever planar frame the caller uses (softsig: the object frame's xy plane).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from softsig_service.errors import InvalidInput

FloatArray = NDArray[np.float64]


def convex_hull_2d(points: ArrayLike) -> FloatArray:
    """Convex hull (counter-clockwise, no repeated end point) of 2D points ``(N, 2)``: qhull's (scipy). Fewer than
    three distinct points, or collinear ones, have no area: their distinct points (at most the two ends) are
    returned, as a degenerate hull."""
    from scipy.spatial import ConvexHull, QhullError

    P = np.unique(np.asarray(points, dtype=np.float64), axis=0)
    if len(P) < 3:
        return P
    try:
        hull = ConvexHull(P)
    except QhullError:  # collinear: the segment's two ends
        d = P - P[0]
        axis = d[np.argmax(np.linalg.norm(d, axis=1))]
        t = d @ axis
        return P[[int(np.argmin(t)), int(np.argmax(t))]]
    return np.asarray(P[hull.vertices], dtype=np.float64)  # counter-clockwise for 2-D input


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
