"""Constructors of :class:`~softsig_service.objects.shape.TableObject` by kind: box, cylinder, sphere,
ellipsoid and triangle mesh, each resting on the table at a pose.

Frames and units: :mod:`softsig_service.objects.shape`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from softsig_service.errors import InvalidInput
from softsig_service.objects.shape import DEFAULT_FRICTION, DEFAULT_X, DEFAULT_Y, TableObject


def box(
    size: Sequence[float],
    mass: float,
    *,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "box",
) -> TableObject:
    """A box of full sizes ``size`` = (sx, sy, sz) [m] along the object's x, y, z, resting on the table."""
    return TableObject("box", tuple(size), mass, friction, x, y, yaw, table_height, z, name=name)


def cylinder(
    radius: float,
    length: float,
    mass: float,
    *,
    standing: bool = False,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "cylinder",
) -> TableObject:
    """A cylinder of ``radius`` and ``length`` [m], lying with its axis along the object's x (centre at
    ``table_height + radius``), or ``standing`` with its axis vertical."""
    return TableObject(
        "cylinder", (radius, length), mass, friction, x, y, yaw, table_height, z, standing=standing, name=name
    )


def sphere(
    radius: float,
    mass: float,
    *,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "sphere",
) -> TableObject:
    """A sphere of ``radius`` [m] resting on the table."""
    return TableObject("sphere", (radius,), mass, friction, x, y, yaw, table_height, z, name=name)


def ellipsoid(
    radii: Sequence[float],
    mass: float,
    *,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "ellipsoid",
) -> TableObject:
    """An ellipsoid with semi-axes ``radii`` = (rx, ry, rz) [m] along the object's x, y, z, on the table."""
    return TableObject("ellipsoid", tuple(radii), mass, friction, x, y, yaw, table_height, z, name=name)


def mesh(
    vertices: ArrayLike,
    faces: ArrayLike,
    mass: float,
    *,
    friction: float = DEFAULT_FRICTION,
    x: float = DEFAULT_X,
    y: float = DEFAULT_Y,
    yaw: float = 0.0,
    table_height: float = 0.0,
    z: float | None = None,
    name: str = "mesh",
) -> TableObject:
    """A triangle mesh (vertices ``(N, 3)`` [m], faces ``(M, 3)`` indices), z up as given; the object frame is
    re-centred on the vertices' bounding box and the mesh rests on the table."""
    try:
        V = np.asarray(vertices, dtype=np.float64)
        F = np.asarray(faces)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("vertices/faces must be rectangular number arrays", field="object.vertices") from exc
    return TableObject("mesh", (), mass, friction, x, y, yaw, table_height, z, vertices=V, faces=F, name=name)
