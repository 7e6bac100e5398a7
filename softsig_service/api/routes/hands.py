"""``/v1/hands``: register (multipart upload), list, get, replace and delete hands.

An upload is a ``hand.toml`` manifest (field ``manifest``), the model file it names (field ``model``: MJCF
``.xml``, URDF ``.urdf`` or xacro ``.urdf.xacro``, stored at the manifest's ``model`` path) and any other files
the model refers to (field ``assets``, repeated; each part's *filename* is its path relative to the hand's folder, e.g.
``meshes/finger.stl``). The files are written into a fresh folder under ``<data_dir>/hands/<name>/`` and the hand
is loaded from there by the hand library in a worker process, with every rule of the library: relative paths that
stay inside the folder (symlinks included), the size limits of ``SOFTSIG_LIMIT_*``, the compiled model's limits.
A hand that fails to load is not registered and its folder is removed.

``POST /v1/hands/archive`` registers a hand from one ``.zip``/``.tar.gz`` (field ``archive``) holding its folder,
read with the rules of :mod:`softsig_service.hands.archive` (every member's path checked, no links, limits on the
member count and the unpacked size). A ``.urdf.xacro`` model is expanded in a limited child process; a
description that reads outside its folder, reads the environment or runs a command gets 422
``unsafe-description``, one that does not end within its limits 422 ``expansion-limit``.
"""

from __future__ import annotations

import hashlib
import tomllib
import uuid
from pathlib import Path as FsPath
from typing import Annotated, Any

from fastapi import APIRouter, File, Path, Request, Response, UploadFile
from starlette.concurrency import run_in_threadpool

from softsig_service import registry as repo
from softsig_service.api.context import AppContext
from softsig_service.api.deps import Ctx, IfMatchRequired, WriteAccess
from softsig_service.api.responses import Answer, AnswerCache, json_response, model_json
from softsig_service.api.routes.common import WRITE, problem, read_route, with_etag
from softsig_service.api.routes.paging import DEFAULT_LIMIT, Limit, Offset, page
from softsig_service.api.schemas import HAND_NAME_PATTERN, HandList, HandOut
from softsig_service.errors import Conflict, InvalidHandModel, InvalidManifest, ModelTooLarge, UnsafePath
from softsig_service.hands.archive import read_archive
from softsig_service.hands.assets import check_relative_path
from softsig_service.hands.manifest import HandManifest, manifest_from_dict
from softsig_service.hands.xacro_expand import CACHE_DIR
from softsig_service.services.serialize import api_json
from softsig_service.services.tasks import inspect_hand

router = APIRouter(prefix="/v1", tags=["hands"])
HandPath = Annotated[str, Path(pattern=HAND_NAME_PATTERN, description="the hand's name")]
_CHUNK = 1 << 20
_MODEL_FILE = "the MJCF (.xml), URDF (.urdf) or xacro (.xacro) file the manifest names"


IF_MATCH: dict[int | str, dict[str, Any]] = {
    412: problem("If-Match does not match the current ETag"),
    428: problem("If-Match is required"),
    **WRITE,
}
"""The responses of a write that needs the hand's ETag in If-Match."""


def hand_summary(record: repo.HandRecord) -> dict[str, Any]:
    """The JSON of :class:`HandSummary` for a record."""
    info = record.info
    return {
        "name": record.name,
        "builtin": record.builtin,
        "revision": record.revision,
        "etag": record.etag,
        "kind": info.get("kind"),
        "description": info.get("description", ""),
        "model_format": info.get("model_format"),
        "reference_points": [p.get("name") for p in info.get("reference_points", [])],
        "signature_count": record.signature_count,
        "created_at": record.created_at,
        "updated_at": record.updated_at,
        "links": {"self": f"/v1/hands/{record.name}", "signatures": f"/v1/hands/{record.name}/signatures"},
    }


def hand_out(record: repo.HandRecord) -> dict[str, Any]:
    """The JSON of :class:`HandOut` for a record."""
    return {**hand_summary(record), "info": api_json(record.info), "files": record.files}


async def _read_limited(upload: UploadFile, limit: int, field: str) -> bytes:
    data = await upload.read(limit + 1)
    if len(data) > limit:
        raise ModelTooLarge(f"file larger than the limit of {limit} bytes", field=field, value=upload.filename)
    return data


def _parse_manifest(data: bytes) -> HandManifest:
    try:
        doc = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise InvalidManifest("the manifest is not UTF-8 text", field="manifest") from None
    except tomllib.TOMLDecodeError as exc:
        raise InvalidManifest(f"the manifest is not valid TOML: {exc}", field="manifest") from None
    try:
        return manifest_from_dict(doc, source="manifest")
    except InvalidManifest as exc:
        raise InvalidManifest(
            exc.message, field=f"manifest.{exc.field}" if exc.field not in (None, "$") else "manifest",
            value=exc.value, choices=exc.choices,
        ) from None  # fmt: skip


def _relative(ref: str, field: str) -> str:
    rel = check_relative_path(ref, field)
    parts = [p for p in rel.parts if p not in ("", ".")]
    if not parts:
        raise UnsafePath("a file path is empty", field=field, value=ref)
    if parts[0] == CACHE_DIR:
        raise UnsafePath(f"{CACHE_DIR}/ is softsig's own cache and cannot be uploaded", field=field, value=ref)
    return "/".join(parts)


async def _write_upload(ctx: Any, manifest: UploadFile, model: UploadFile, assets: list[UploadFile],
                        expect_name: str | None) -> tuple[HandManifest, FsPath, list[dict[str, Any]]]:  # fmt: skip
    """Check the upload and write it into a fresh folder; returns the manifest, the folder and the file list."""
    limits = ctx.settings.limits
    manifest_bytes = await _read_limited(manifest, limits.max_model_bytes, "manifest")
    man = _parse_manifest(manifest_bytes)
    if expect_name is not None and man.name != expect_name:
        raise InvalidManifest("the manifest's name must be the hand's name", field="manifest.name", value=man.name,
                              choices=[expect_name])  # fmt: skip
    model_rel = _relative(man.model, "manifest.model")
    model_suffix = FsPath(model_rel).suffix.lower()
    if FsPath(model.filename or "").suffix.lower() != model_suffix:
        raise InvalidHandModel(
            f"the model file must be the {model_suffix} file the manifest names", field="model",
            value=model.filename, choices=[model_suffix],
        )  # fmt: skip
    files: dict[str, bytes] = {"hand.toml": manifest_bytes}
    fields = {"hand.toml": "manifest", model_rel: "model"}
    files[model_rel] = await _read_limited(model, limits.max_model_bytes, "model")
    if len(assets) > limits.max_assets:
        raise ModelTooLarge(f"more than {limits.max_assets} asset files", field="assets", value=len(assets))
    total = sum(len(b) for b in files.values())
    for k, upload in enumerate(assets):
        field = f"assets[{k}]"
        rel = _relative(upload.filename or "", field)
        if rel in files or rel.lower() == "hand.toml":
            raise InvalidHandModel("two files have the same path", field=field, value=rel)
        fields[rel] = field
        files[rel] = await _read_limited(upload, limits.max_asset_bytes, field)
        total += len(files[rel])
        if total > limits.max_total_bytes:
            raise ModelTooLarge(f"the hand's files exceed {limits.max_total_bytes} bytes", field=field, value=total)
    folder, listing = await _store(ctx, man, files, fields)
    return man, folder, listing


def _check_layout(files: dict[str, bytes], fields: dict[str, str]) -> None:
    """No file may also be a folder of another (``a`` and ``a/b.stl``), whatever their order."""
    folders = {"/".join(rel.split("/")[:k]): rel for rel in files for k in range(1, rel.count("/") + 1)}
    for rel in files:
        if rel in folders:
            raise InvalidHandModel("a file has the path of another file's folder", field=fields.get(rel, "archive"),
                                   value=rel, choices=[folders[rel]])  # fmt: skip


async def _store(
    ctx: Any, man: HandManifest, files: dict[str, bytes], fields: dict[str, str] | None = None
) -> tuple[FsPath, list[dict[str, Any]]]:
    """Write checked files into a fresh folder of the hand; returns the folder and the file list."""
    _check_layout(files, fields or {})
    folder = ctx.hands_dir / man.name / uuid.uuid4().hex

    def write() -> list[dict[str, Any]]:
        listing = []
        for rel, data in files.items():
            path = (folder / rel).resolve()
            if not path.is_relative_to(folder.resolve()):
                raise UnsafePath("file path leaves the hand's folder", field="assets", value=rel)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_bytes(data)
            except OSError:
                where = (fields or {}).get(rel, "archive")
                raise InvalidHandModel("the file cannot be stored at this path", field=where, value=rel) from None
            listing.append({"path": rel, "size": len(data), "sha256": hashlib.sha256(data).hexdigest()})
        return listing

    folder.mkdir(parents=True)
    try:
        listing = await run_in_threadpool(write)
    except BaseException:
        repo.remove_hand_folder(folder)
        raise
    return folder, listing


@router.get("/hands", response_model=HandList, **read_route(), summary="List hands")
def list_hands(ctx: Ctx, limit: Limit = DEFAULT_LIMIT, offset: Offset = 0) -> dict[str, Any]:
    """The registered hands (built in and uploaded), by name."""
    return page([hand_summary(r) for r in repo.list_hands(ctx.registry)], limit, offset)


_REGISTER: dict[str, Any] = {
    "status_code": 201,
    "response_model": HandOut,
    "dependencies": [WriteAccess],
    "responses": {409: problem("a hand of this name is registered already"), **WRITE},
}


@router.post("/hands", summary="Register a hand (multipart: manifest, model, assets)", **_REGISTER)
async def register_hand(
    ctx: Ctx,
    response: Response,
    manifest: Annotated[UploadFile, File(description="hand.toml")],
    model: Annotated[UploadFile, File(description=_MODEL_FILE)],
    assets: Annotated[
        list[UploadFile] | None, File(description="other files (meshes, includes); filename = relative path")
    ] = None,
) -> dict[str, Any]:
    """Upload and register a new hand; 201 with its summary, ``Location`` and ``ETag``."""
    man, folder, listing = await _write_upload(ctx, manifest, model, assets or [], None)
    return await _register(ctx, response, man, folder, listing)


@router.post("/hands/archive", summary="Register a hand from one archive (.zip, .tar.gz) of its folder", **_REGISTER)
async def register_hand_archive(
    ctx: Ctx,
    response: Response,
    archive: Annotated[UploadFile, File(description="a .zip or .tar.gz with hand.toml at its top (or in one folder)")],
) -> dict[str, Any]:
    """Upload a hand's folder as one archive and register it; 201 with its summary, ``Location`` and ``ETag``."""
    limits = ctx.settings.limits
    data = await _read_limited(archive, limits.max_total_bytes, "archive")
    files = await run_in_threadpool(read_archive, data, archive.filename or "", limits)
    man = _parse_manifest(files["hand.toml"])
    model_rel = _relative(man.model, "manifest.model")
    if model_rel not in files:
        raise InvalidHandModel("the archive lacks the model file the manifest names", field="manifest.model",
                               value=man.model)  # fmt: skip
    folder, listing = await _store(ctx, man, files)
    return await _register(ctx, response, man, folder, listing)


async def _register(
    ctx: Any, response: Response, man: HandManifest, folder: FsPath, listing: list[dict[str, Any]]
) -> dict[str, Any]:
    """Load the stored hand in a worker and add it to the registry (its folder is removed on any failure)."""
    try:
        if man.name in await run_in_threadpool(repo.hand_names, ctx.registry):
            raise Conflict("a hand of this name is registered already", field="manifest.name", value=man.name)
        info = await ctx.pool.run(
            inspect_hand, str(folder / "hand.toml"), ctx.settings.limits, what="loading the hand model", field="model"
        )
        record = await run_in_threadpool(
            lambda: repo.add_hand(
                ctx.registry, name=man.name, manifest_path=str(folder / "hand.toml"), info=info, files=listing,
                folder=str(folder),
            )
        )  # fmt: skip
    except BaseException:
        repo.remove_hand_folder(folder)
        raise
    response.headers["Location"] = f"/v1/hands/{record.name}"
    return hand_out(with_etag(response, record))


@router.get(
    "/hands/{hand}",
    response_model=HandOut,
    **read_route({304: {"description": "If-None-Match matched the current ETag"}}),
    summary="Get a hand",
)
async def get_hand(hand: HandPath, request: Request) -> Any:
    """A hand with its model summary; ``ETag`` for ``If-Match`` on updates (``If-None-Match`` gives 304)."""
    ctx: AppContext = request.app.state.ctx  # not the Ctx dependency: one level less to solve on a hot read
    stamp = repo.hand_stamp(ctx.registry, hand)  # one indexed row, on the loop (api/responses.py)
    if stamp is None:  # HandNotFound, with the registered names (or one registered meanwhile)
        await run_in_threadpool(repo.get_hand, ctx.registry, hand)

    def make() -> tuple[Any, Answer]:
        record = repo.get_hand(ctx.registry, hand)
        return repo.stamp_of(record), (record.etag, model_json(HandOut, hand_out(record)))

    etag, body = await HAND_ANSWERS.aget(stamp, make)
    inm = request.headers.get("if-none-match")
    if inm is not None and repo.etag_matches(etag, inm):
        return Response(status_code=304, headers={"ETag": etag})
    return json_response(body, headers={"ETag": etag})


HAND_ANSWERS = AnswerCache(4 << 20)
"""``GET /v1/hands/{hand}``'s answers by the hand's stamp (:func:`softsig_service.registry.hand_stamp`), 4 MiB
at most."""


@router.put(
    "/hands/{hand}",
    response_model=HandOut,
    dependencies=[WriteAccess],
    responses={
        409: problem("built-in hands cannot be replaced"),
        **IF_MATCH,
    },
    summary="Replace an uploaded hand's files (needs If-Match)",
)
async def replace_hand(
    ctx: Ctx,
    hand: HandPath,
    response: Response,
    if_match: IfMatchRequired,
    manifest: Annotated[UploadFile, File(description="hand.toml (its name must be the hand's)")],
    model: Annotated[UploadFile, File(description=_MODEL_FILE)],
    assets: Annotated[list[UploadFile] | None, File(description="other files; filename = relative path")] = None,
) -> dict[str, Any]:
    """Replace the files of an uploaded hand; its revision (and ETag) changes, its signatures stay (each records
    the revision it was computed from)."""
    current = await run_in_threadpool(repo.get_hand, ctx.registry, hand)
    if current.builtin:
        raise Conflict("built-in hands cannot be replaced", field="hand", value=hand)
    if if_match is not None and not repo.etag_matches(current.etag, if_match):
        from softsig_service.errors import PreconditionFailed

        raise PreconditionFailed("If-Match does not match the hand's current ETag", field="If-Match",
                                 value=if_match, choices=[current.etag])  # fmt: skip
    _, folder, listing = await _write_upload(ctx, manifest, model, assets or [], hand)
    try:
        info = await ctx.pool.run(
            inspect_hand, str(folder / "hand.toml"), ctx.settings.limits, what="loading the hand model", field="model"
        )
        record, old = await run_in_threadpool(
            lambda: repo.replace_hand(
                ctx.registry, hand, if_match=if_match, manifest_path=str(folder / "hand.toml"), folder=str(folder),
                files=listing, info=info,
            )
        )  # fmt: skip
    except BaseException:
        repo.remove_hand_folder(folder)
        raise
    repo.remove_hand_folder(old)
    return hand_out(with_etag(response, record))


@router.delete(
    "/hands/{hand}",
    status_code=204,
    response_class=Response,
    dependencies=[WriteAccess],
    responses={
        409: problem("built-in hands cannot be deleted"),
        **IF_MATCH,
    },
    summary="Delete an uploaded hand and its signatures (needs If-Match)",
)
def delete_hand(ctx: Ctx, hand: HandPath, if_match: IfMatchRequired) -> Response:
    """Delete an uploaded hand, its signature versions and its files. Stored plans of it stay."""
    record = repo.delete_hand(ctx.registry, hand, if_match=if_match)
    repo.remove_hand_folder(record.folder)
    return Response(status_code=204)
