"""The object registry: ``POST /v1/objects`` (any object JSON) and ``POST /v1/objects/files`` (a mesh or cloud
file) register an object once; plans and validations then name it (``{"kind": "stored", "id": ...}``), so that
large geometry is sent once and its collision structures are built once (they are cached by content)."""

from __future__ import annotations

import json
from typing import Annotated, Any

from fastapi import APIRouter, File, Form, Path, Response, UploadFile
from pydantic import ValidationError
from starlette.concurrency import run_in_threadpool
from starlette.convertors import Convertor, register_url_convertor

from softsig_service import registry as repo
from softsig_service.api.deps import Ctx
from softsig_service.api.object_schemas import ObjectIn, ObjectList, ObjectOut
from softsig_service.api.routes.common import problem, read_route, write_route
from softsig_service.api.routes.paging import DEFAULT_LIMIT, Limit, Offset, page_of
from softsig_service.api.scene import scene_object
from softsig_service.errors import InvalidInput
from softsig_service.objects import TableObject
from softsig_service.objects.schema import (
    FRAME_PATTERN,
    MIN_MASS,
    OBJECT_ID_PATTERN,
    OBJECT_SPEC,
    UNION_TAGS,
    WORLD_FRAME,
    SceneFields,
)
from softsig_service.services.serialize import vector_json
from softsig_service.validation import invalid_input

router = APIRouter(prefix="/v1", tags=["objects"])
ObjectId = Annotated[str, Path(pattern=OBJECT_ID_PATTERN, description="a registered object's id")]


class _ObjectIdConvertor(Convertor[str]):
    """Path segments that can be an object's id (32 hex digits): ``/v1/objects/files`` is then the file route's
    resource only, and another method on it is 405, not a 422 about an id."""

    regex = OBJECT_ID_PATTERN.strip("^$")

    def convert(self, value: str) -> str:
        return value

    def to_string(self, value: str) -> str:
        return value


register_url_convertor("object_id", _ObjectIdConvertor())


def _links(object_id: str) -> dict[str, str]:
    return {"self": f"/v1/objects/{object_id}"}


def _out(rec: repo.ObjectRecord) -> dict[str, Any]:
    from softsig_service.objects import object_from_json

    obj = object_from_json(rec.spec, table_height=rec.table_height)
    return {
        "id": rec.id, "name": rec.name, "source": rec.source, "object": rec.spec, "table_height": rec.table_height,
        "o1": vector_json(obj.o1), "o2": vector_json(obj.o2), "extent_major": obj.extent_major,
        "extent_minor": obj.extent_minor, "height": obj.height, "created_at": rec.created_at, "links": _links(rec.id),
    }  # fmt: skip


def _register(ctx: Any, obj: TableObject, name: str, source: str, response: Response) -> dict[str, Any]:
    rec = repo.add_object(ctx.registry, name=(name or obj.name)[:64], source=source, spec=obj.to_json(),
                          table_height=obj.table_height)  # fmt: skip
    response.headers["Location"] = f"/v1/objects/{rec.id}"
    return _out(rec)


CREATED = {"status_code": 201, "response_model": ObjectOut, **write_route({422: problem("the object is refused")})}


@router.post("/objects", **CREATED, summary="Register an object (any object JSON)")
async def create_object(ctx: Ctx, body: ObjectIn, response: Response) -> dict[str, Any]:
    """Register ``object`` (a primitive, a mesh, a cloud in any frame of ``frames``: its conservative solid, a
    tabletop: its picked cluster) on the table at ``table.height``; 201 with ``Location``."""
    if body.object.kind == "stored":
        raise InvalidInput("register the object itself, not a registered one", field="object.kind", value="stored")
    obj = await run_in_threadpool(scene_object, body.object, body)
    return _register(ctx, obj, body.name, body.object.kind, response)


@router.post("/objects/files", **CREATED, summary="Register an object from a mesh or point-cloud file")
async def create_object_from_file(
    ctx: Ctx,
    response: Response,
    file: Annotated[UploadFile, File(description="STL (binary or ASCII), OBJ or PLY mesh; PCD or PLY cloud")],
    mass: Annotated[float, Form(ge=MIN_MASS, le=1000.0, description="[kg]")],
    name: Annotated[str, Form(max_length=64)] = "",
    scale: Annotated[float, Form(gt=0.0, le=1000.0, description="factor on the file's coordinates (mm: 0.001)")] = 1.0,
    frame_id: Annotated[str, Form(pattern=FRAME_PATTERN, description="a cloud's frame")] = WORLD_FRAME,
    frames: Annotated[str, Form(max_length=65_536, description="JSON: poses in base_link of the frames named")] = "{}",
    table_height: Annotated[float, Form(ge=-10.0, le=10.0, description="[m] the table top")] = 0.0,
) -> dict[str, Any]:
    """Read the file (trimesh, pypcd4): a mesh keeps its axes, z up, and rests on the table; a cloud becomes its
    conservative solid; 201 with ``Location``. Malformed, empty or oversized files are 422 (``file``); over the
    upload limit 413."""
    from softsig_service.objects.files import object_from_file

    try:
        scene = SceneFields.model_validate({"frames": json.loads(frames), "table": {"height": table_height}})
    except (json.JSONDecodeError, ValueError) as exc:
        raise InvalidInput(f"frames must be a JSON object of poses: {exc}", field="frames") from None
    data = await file.read()
    filename = file.filename or "object"
    spec = await run_in_threadpool(
        lambda: object_from_file(data, filename, mass=mass, scale=scale, frame_id=frame_id, field="file")
    )
    try:  # the file's contents against the schema's ranges (coordinates within 10 m: a file in mm needs scale)
        model = OBJECT_SPEC.validate_python(spec)
    except ValidationError as exc:
        problem = invalid_input(exc, "file", UNION_TAGS)
        raise InvalidInput(f"the file's object is out of range: {problem}", field="file", value=filename) from None
    obj = await run_in_threadpool(scene_object, model, scene, "file")
    source = filename.rsplit(".", 1)[-1].lower()
    return _register(ctx, obj, name or filename.rsplit(".", 1)[0], source, response)


@router.get("/objects", response_model=ObjectList, **read_route(), summary="List registered objects")
def list_objects(ctx: Ctx, limit: Limit = DEFAULT_LIMIT, offset: Offset = 0) -> dict[str, Any]:
    """Registered objects, newest first (``limit``, ``offset``)."""
    items, total = repo.list_objects(ctx.registry, limit=limit, offset=offset)
    rows = [{"id": r.id, "name": r.name, "source": r.source, "created_at": r.created_at, "links": _links(r.id)}
            for r in items]  # fmt: skip
    return page_of(rows, total, limit, offset)


@router.get("/objects/{object_id:object_id}", response_model=ObjectOut, **read_route({404: problem("no such object")}),
            summary="Get a registered object")  # fmt: skip
def get_object(ctx: Ctx, object_id: ObjectId) -> dict[str, Any]:
    """A registered object with its geometry and what the planner derives from it."""
    return _out(repo.get_object(ctx.registry, object_id))


@router.delete("/objects/{object_id:object_id}", status_code=204, response_class=Response,
               **write_route({404: problem("no such object")}), summary="Delete a registered object")  # fmt: skip
def delete_object(ctx: Ctx, object_id: ObjectId) -> Response:
    """Remove a registered object; 404 if there is none. Plans stored with it keep their copy of the object."""
    repo.delete_object(ctx.registry, object_id)
    return Response(status_code=204)
