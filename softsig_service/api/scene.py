"""The scene of a request: its object and obstacles in ``base_link``, on its table, from whichever frame they were
given in, registered objects (``{"kind": "stored", "id": ...}``) looked up."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from pydantic import BaseModel

from softsig_service.api.context import AppContext
from softsig_service.errors import InvalidInput, NotFound
from softsig_service.objects import TableObject
from softsig_service.objects.schema import SceneFields, object_json

StoredLookup = Callable[[str], tuple[dict[str, Any], float]]
"""A registered object's JSON and table height [m] by its id (raises :class:`NotFound` for an unknown one)."""


def scene_frames(scene: SceneFields) -> dict[str, Any]:
    """The 4x4 poses in ``base_link`` of the frames ``scene`` gives (:func:`~softsig_service.objects.frames.
    frame_transforms`)."""
    from softsig_service.objects.frames import frame_transforms

    return frame_transforms(scene.model_dump(include={"frames"})["frames"])


def stored_objects(ctx: AppContext) -> StoredLookup:
    """The lookup of the objects registered with the service of ``ctx``."""
    from softsig_service import registry as repo

    def lookup(object_id: str) -> tuple[dict[str, Any], float]:
        rec = repo.get_object(ctx.registry, object_id)
        return rec.spec, rec.table_height

    return lookup


def _json(spec: BaseModel, stored: StoredLookup | None, field: str) -> tuple[dict[str, Any], float | None]:
    """The object JSON of ``spec`` and, for a stored object, the table height it was registered on: its registered
    JSON with the request's pose, mass or friction in place of its own."""
    data = object_json(spec)
    if data.get("kind") != "stored":
        return data, None
    if stored is None:
        raise InvalidInput("registered objects are not taken here", field=f"{field}.kind", value="stored")
    try:
        found, table_height = stored(data["id"])
    except NotFound:
        raise InvalidInput("no object is registered under this id", field=f"{field}.id", value=data["id"]) from None
    registered = dict(found)
    for key in ("pose", "mass", "friction"):
        if key in data:
            registered[key] = data[key]
    return registered, table_height


def scene_object(
    spec: BaseModel, scene: SceneFields, field: str = "object", stored: StoredLookup | None = None
) -> TableObject:
    """The object ``spec`` (an :data:`~softsig_service.objects.schema.ObjectSpec`) of a request with ``scene``'s
    ``table`` and ``frames`` (plans, validations): in ``base_link``, on the table; a point cloud becomes its
    conservative solid, a stored object is found with ``stored`` (on its registered table unless the request
    states one). Raises
    :class:`~softsig_service.errors.InvalidInput` naming the field (``field`` its path)."""
    from softsig_service.objects import object_from_json

    frames = scene_frames(scene)
    data, registered_table = _json(spec, stored, field)
    table = scene.table.height
    if registered_table is not None and "table" not in scene.model_fields_set:
        table = registered_table  # a stored object stands on the table it was registered on, unless told otherwise
    return object_from_json(data, table_height=table, frames=frames, field=field)


def scene_obstacles(
    specs: Sequence[BaseModel], scene: SceneFields, stored: StoredLookup | None = None
) -> tuple[TableObject, ...]:
    """The ``obstacles`` of a request, each as :func:`scene_object` makes it (fields ``obstacles[i]...``)."""
    return tuple(scene_object(spec, scene, f"obstacles[{i}]", stored) for i, spec in enumerate(specs))


def scene_objects(
    spec: BaseModel, obstacles: Sequence[BaseModel], scene: SceneFields, stored: StoredLookup | None = None
) -> tuple[TableObject, tuple[TableObject, ...]]:
    """A plan's target and obstacles. A ``tabletop`` target brings the other clusters of its cloud as obstacles
    (first) and its table plane: the request's ``obstacles`` are then placed on that table."""
    from softsig_service.objects.parse import tabletop_objects

    if getattr(spec, "kind", None) != "tabletop":
        return scene_object(spec, scene, stored=stored), scene_obstacles(obstacles, scene, stored)
    frames = scene_frames(scene)
    target, others, seg = tabletop_objects(object_json(spec), frames)
    on_its_table = scene.model_copy(update={"table": scene.table.model_copy(update={"height": seg.height})})
    return target, (*others, *scene_obstacles(obstacles, on_its_table, stored))
