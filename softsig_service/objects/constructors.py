"""Constructors of :class:`~softsig_service.objects.shape.TableObject` by kind: box, cylinder, sphere,
ellipsoid and triangle mesh, each resting on the table at a pose.

Every constructor takes the same keyword arguments (:class:`Placement`): ``friction`` (default 1.0), the pose
``x`` [m] (default 0.5), ``y`` [m] (default 0), ``yaw`` [rad] (default 0), ``table_height`` [m] (default 0), an
explicit centre height ``z`` [m] (default: resting on the table) and a ``name`` (default the kind). Frames and
units: :mod:`softsig_service.objects.shape`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, TypedDict

import numpy as np
from numpy.typing import ArrayLike
from typing_extensions import Unpack

from softsig_service.errors import InvalidInput
from softsig_service.objects.shape import DEFAULT_FRICTION, DEFAULT_X, DEFAULT_Y, TableObject


class Placement(TypedDict, total=False):
    """Where and how an object rests on the table (the keyword arguments of every constructor)."""

    friction: float
    x: float
    y: float
    yaw: float
    table_height: float
    z: float | None
    name: str


def _make(kind: str, dims: tuple[float, ...], mass: float, placement: Placement, **shape: Any) -> TableObject:
    p = placement
    return TableObject(
        kind, dims, mass, p.get("friction", DEFAULT_FRICTION), p.get("x", DEFAULT_X), p.get("y", DEFAULT_Y),  # type: ignore[arg-type]
        p.get("yaw", 0.0), p.get("table_height", 0.0), p.get("z"), name=p.get("name", kind), **shape,
    )  # fmt: skip


def box(size: Sequence[float], mass: float, **placement: Unpack[Placement]) -> TableObject:
    """A box of full sizes ``size`` = (sx, sy, sz) [m] along the object's x, y, z, resting on the table."""
    return _make("box", tuple(size), mass, placement)


def cylinder(
    radius: float, length: float, mass: float, *, standing: bool = False, **placement: Unpack[Placement]
) -> TableObject:
    """A cylinder of ``radius`` and ``length`` [m], lying with its axis along the object's x (centre at
    ``table_height + radius``), or ``standing`` with its axis vertical."""
    return _make("cylinder", (radius, length), mass, placement, standing=standing)


def sphere(radius: float, mass: float, **placement: Unpack[Placement]) -> TableObject:
    """A sphere of ``radius`` [m] resting on the table."""
    return _make("sphere", (radius,), mass, placement)


def ellipsoid(radii: Sequence[float], mass: float, **placement: Unpack[Placement]) -> TableObject:
    """An ellipsoid with semi-axes ``radii`` = (rx, ry, rz) [m] along the object's x, y, z, on the table."""
    return _make("ellipsoid", tuple(radii), mass, placement)


def mesh(
    vertices: ArrayLike, faces: ArrayLike, mass: float, *, own_axes: ArrayLike | None = None,
    **placement: Unpack[Placement],
) -> TableObject:  # fmt: skip
    """A triangle mesh (vertices ``(N, 3)`` [m], faces ``(M, 3)`` indices), z up as given; the object frame is
    re-centred on the vertices' bounding box and the mesh rests on the table. ``own_axes``: the major, minor and
    up axes (3x3, columns, base_link) of an object turned into this mesh."""
    try:
        V = np.asarray(vertices, dtype=np.float64)
        F = np.asarray(faces)
    except (TypeError, ValueError) as exc:
        raise InvalidInput("vertices/faces must be rectangular number arrays", field="object.vertices") from exc
    axes = None if own_axes is None else np.asarray(own_axes, dtype=np.float64).reshape(3, 3)
    return _make("mesh", (), mass, placement, vertices=V, faces=F, own_axes=axes)
