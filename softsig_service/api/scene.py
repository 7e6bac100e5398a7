"""The scene of a request: its object and obstacles in ``base_link``, on its table, from whichever frame they were
given in."""

from __future__ import annotations

from collections.abc import Sequence

from pydantic import BaseModel

from softsig_service.objects import TableObject
from softsig_service.objects.schema import SceneFields, object_json


def scene_object(spec: BaseModel, scene: SceneFields, field: str = "object") -> TableObject:
    """The object ``spec`` (an :data:`~softsig_service.objects.schema.ObjectSpec`) of a request with ``scene``'s
    ``table`` and ``frames`` (plans, validations): in ``base_link``, on the table; a point cloud becomes its
    conservative solid. Raises :class:`~softsig_service.errors.InvalidInput` naming the field (``field`` its
    path)."""
    from softsig_service.objects import object_from_json
    from softsig_service.objects.frames import frame_transforms

    frames = frame_transforms(scene.model_dump(include={"frames"})["frames"])
    return object_from_json(object_json(spec), table_height=scene.table.height, frames=frames, field=field)


def scene_obstacles(specs: Sequence[BaseModel], scene: SceneFields) -> tuple[TableObject, ...]:
    """The ``obstacles`` of a request, each as :func:`scene_object` makes it (fields ``obstacles[i]...``)."""
    return tuple(scene_object(spec, scene, f"obstacles[{i}]") for i, spec in enumerate(specs))


def scene_objects(
    spec: BaseModel, obstacles: Sequence[BaseModel], scene: SceneFields
) -> tuple[TableObject, tuple[TableObject, ...]]:
    """A plan's target and obstacles. A ``tabletop`` target brings the other clusters of its cloud as obstacles
    (first) and its table plane: the request's ``obstacles`` are then placed on that table."""
    from softsig_service.objects.frames import frame_transforms
    from softsig_service.objects.parse import tabletop_objects

    if getattr(spec, "kind", None) != "tabletop":
        return scene_object(spec, scene), scene_obstacles(obstacles, scene)
    frames = frame_transforms(scene.model_dump(include={"frames"})["frames"])
    target, others, seg = tabletop_objects(object_json(spec), frames)
    on_its_table = scene.model_copy(update={"table": scene.table.model_copy(update={"height": seg.height})})
    return target, (*others, *scene_obstacles(obstacles, on_its_table))
