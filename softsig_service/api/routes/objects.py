"""The object registry: ``POST /v1/objects`` (any object JSON, or a mesh or cloud file as a multipart upload)
registers an object once; plans and validations then name it (``{"kind": "stored", "id": ...}``), so that
large geometry is sent once and its collision structures are built once (they are cached by content)."""

from __future__ import annotations

import json
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Path, Request, Response
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from starlette.concurrency import run_in_threadpool
from starlette.convertors import Convertor, register_url_convertor
from starlette.datastructures import UploadFile

from softsig_service import registry as repo
from softsig_service.api.deps import Ctx
from softsig_service.api.object_schemas import ObjectIn, ObjectList, ObjectOut
from softsig_service.api.routes.common import problem, read_route, write_route
from softsig_service.api.routes.paging import DEFAULT_LIMIT, Limit, Offset, page_of
from softsig_service.api.scene import scene_frames, scene_object
from softsig_service.errors import InvalidInput, UnsupportedMediaType
from softsig_service.objects import TableObject
from softsig_service.objects.schema import (
    FRAME_PATTERN,
    MIN_MASS,
    OBJECT_ID_PATTERN,
    WORLD_FRAME,
    SceneFields,
)
from softsig_service.services.serialize import vector_json

router = APIRouter(prefix="/v1", tags=["objects"])
ObjectId = Annotated[str, Path(pattern=OBJECT_ID_PATTERN, description="a registered object's id")]


class _ObjectIdConvertor(Convertor[str]):
    """Path segments that can be an object's id (32 hex digits): another path under ``/v1/objects/`` is then no
    resource (404), not a 422 about an id."""

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


class ObjectFileFields(BaseModel):
    """The form fields beside the multipart ``file`` of ``POST /v1/objects`` (form values are text: numbers as
    decimal strings, ``frames`` as JSON)."""

    model_config = ConfigDict(extra="forbid")

    mass: float = Field(ge=MIN_MASS, le=1000.0, description="[kg]")
    kind: Literal["mesh", "points"] | None = Field(
        None, description="read the file as a mesh or as a cloud (its vertices); default: a mesh if it has faces"
    )
    name: str = Field("", max_length=64)
    scale: float = Field(1.0, gt=0.0, le=1000.0, description="factor on the file's coordinates (mm: 0.001)")
    frame_id: str = Field(WORLD_FRAME, pattern=FRAME_PATTERN, description="a cloud's frame")
    frames: str = Field("{}", max_length=65_536, description="JSON: poses in base_link of the frames named")
    table_height: float = Field(0.0, ge=-10.0, le=10.0, description="[m] the table top")


_FORM_SCHEMA: dict[str, Any] = ObjectFileFields.model_json_schema()
_FORM_SCHEMA["properties"] = {
    "file": {"type": "string", "format": "binary",
             "description": "STL (binary or ASCII), OBJ or PLY mesh; PCD or PLY cloud"},
    **_FORM_SCHEMA["properties"],
}  # fmt: skip
_FORM_SCHEMA["required"] = ["file", *_FORM_SCHEMA.get("required", [])]
_FORM_SCHEMA["title"] = "ObjectFileIn"
BODIES: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": {"$ref": "#/components/schemas/ObjectIn"}},
            "multipart/form-data": {"schema": _FORM_SCHEMA},
        },
    }
}
"""The two bodies ``POST /v1/objects`` takes (the route reads its body itself: FastAPI routes one media type)."""
JSON_TYPES = ("application/json", "")
"""Media types read as JSON (none given: JSON, as FastAPI does)."""


def _validation_error(exc: ValidationError) -> RequestValidationError:
    """A pydantic error of the body as FastAPI raises it (locations under ``body``): one 422 for every route."""
    return RequestValidationError([{**e, "loc": ("body", *e["loc"])} for e in exc.errors()])


@router.post("/objects", **CREATED, openapi_extra=BODIES, summary="Register an object (object JSON or a file)")
async def create_object(ctx: Ctx, request: Request, response: Response) -> dict[str, Any]:
    """Register an object once; 201 with ``Location``.

    - ``application/json``: ``object`` (a primitive, a mesh, a cloud in any frame of ``frames``: its conservative
      solid, a tabletop: its picked cluster) on the table at ``table.height``.
    - ``multipart/form-data``: a mesh or cloud ``file`` read with trimesh or pypcd4 (a mesh keeps its axes, z up,
      and rests on the table; a cloud in ``frame_id`` becomes its conservative solid) with ``mass`` and the other
      form fields. Malformed, empty or oversized files are 422 (``file``); over the upload limit 413.
    - another media type: 415."""
    media = request.headers.get("content-type", "").split(";", 1)[0].strip().lower()
    if media == "multipart/form-data":
        return await _from_form(ctx, request, response)
    if media not in JSON_TYPES and not media.endswith("+json"):
        raise UnsupportedMediaType("the body is an object JSON (application/json) or a file (multipart/form-data)",
                                   field="Content-Type", value=media, choices=("application/json",
                                                                                "multipart/form-data"))  # fmt: skip
    raw = await request.body()
    try:
        data = json.loads(raw)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        pos = getattr(exc, "pos", getattr(exc, "start", 0))
        raise RequestValidationError([{"type": "json_invalid", "loc": ("body", pos), "msg": "JSON decode error",
                                       "input": {}, "ctx": {"error": str(exc)}}]) from None  # fmt: skip
    try:
        body = ObjectIn.model_validate(data)
    except ValidationError as exc:
        raise _validation_error(exc) from None
    if body.object.kind == "stored":
        raise InvalidInput("register the object itself, not a registered one", field="object.kind", value="stored")
    obj = await run_in_threadpool(scene_object, body.object, body)
    return _register(ctx, obj, body.name, body.object.kind, response)


async def _from_form(ctx: Any, request: Request, response: Response) -> dict[str, Any]:
    from softsig_service.objects import object_from_json
    from softsig_service.objects.files import object_from_file

    async with request.form(max_files=1, max_fields=len(ObjectFileFields.model_fields)) as form:
        names = [k for k, _ in form.multi_items()]
        twice = next((k for k in names if names.count(k) > 1), None)
        if twice is not None:
            raise InvalidInput("a form field is given twice", field=twice)
        files = form.getlist("file")
        fields = {k: v for k, v in form.items() if k != "file"}
        if len(files) != 1 or not isinstance(files[0], UploadFile):
            raise InvalidInput("the form needs one file part named 'file'", field="file")
        try:
            form_fields = ObjectFileFields.model_validate(fields)
            scene = SceneFields.model_validate({"frames": json.loads(form_fields.frames),
                                                "table": {"height": form_fields.table_height}})  # fmt: skip
        except ValidationError as exc:
            raise _validation_error(exc) from None
        except json.JSONDecodeError as exc:
            raise InvalidInput(f"frames must be a JSON object of poses: {exc}", field="frames") from None
        upload = files[0]
        data = await upload.read()
        filename = upload.filename or "object"
    f = form_fields
    spec = await run_in_threadpool(
        lambda: object_from_file(
            data, filename, mass=f.mass, scale=f.scale, frame_id=f.frame_id, kind=f.kind, field="file"
        )
    )
    frames = scene_frames(scene)
    obj = await run_in_threadpool(
        lambda: object_from_json(spec, table_height=scene.table.height, frames=frames, field="file")
    )
    source = filename.rsplit(".", 1)[-1].lower()
    return _register(ctx, obj, f.name or filename.rsplit(".", 1)[0], source, response)


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
