"""Real household objects shipped with the package: meshes of a mug, a banana, a power drill and a mustard bottle
(``softsig_service/objects/meshes/``, whose README gives each file's source, licence and mass citation).

Each is a ``mesh`` object JSON (vertices [m] in the object's own frame, z up, resting on its base as the source gives
it) with the published or stated mass [kg]; a request names one as ``{"kind": "builtin", "name": "mug"}``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Any

from softsig_service.errors import InvalidInput
from softsig_service.objects.shape import HOUSEHOLD_NAMES


@dataclass(frozen=True)
class HouseholdObject:
    """One shipped object: its file in ``meshes/``, mass [kg] and where both come from."""

    file: str
    mass: float
    source: str


HOUSEHOLD: dict[str, HouseholdObject] = {
    "mug": HouseholdObject("mug.ply", 0.30, "pybullet 3.2.7 pybullet_data/objects/mug.obj (zlib); mass approximate"),
    "banana": HouseholdObject("banana.ply", 0.066, "YCB 011_banana (CC BY 4.0); mass as published"),
    "power_drill": HouseholdObject("power_drill.ply", 0.895, "YCB 035_power_drill (CC BY 4.0); mass as published"),
    "mustard_bottle": HouseholdObject(
        "mustard_bottle.ply", 0.603, "YCB 006_mustard_bottle (CC BY 4.0); mass as published"
    ),
}
assert tuple(HOUSEHOLD) == HOUSEHOLD_NAMES


@cache
def _mesh_arrays(name: str) -> tuple[tuple[tuple[float, ...], ...], tuple[tuple[int, ...], ...]]:
    """The vertices [m] and triangles of a shipped mesh, read once per process (the package's files do not change
    while it runs)."""
    from softsig_service.objects.files import object_from_file

    data = resources.files("softsig_service.objects").joinpath("meshes", HOUSEHOLD[name].file).read_bytes()
    spec = object_from_file(data, HOUSEHOLD[name].file, mass=HOUSEHOLD[name].mass)
    return tuple(map(tuple, spec["vertices"])), tuple(map(tuple, spec["faces"]))


def household_json(name: str) -> dict[str, Any]:
    """The ``mesh`` object JSON of the shipped object ``name`` (no pose: the default one), with its mass [kg].
    Raises :class:`InvalidInput` listing the choices for an unknown name."""
    if name not in HOUSEHOLD:
        raise InvalidInput(f"unknown household object {name!r}", field="object.name", value=name,
                           choices=HOUSEHOLD_NAMES)  # fmt: skip
    vertices, faces = _mesh_arrays(name)
    return {"kind": "mesh", "vertices": [list(v) for v in vertices], "faces": [list(f) for f in faces],
            "mass": HOUSEHOLD[name].mass, "name": name}  # fmt: skip
