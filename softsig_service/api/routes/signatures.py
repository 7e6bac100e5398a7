"""``/v1/hands/{hand}/signatures``: compute and store signature versions, list them, get one or the latest.

Versions are numbered per hand (closure and stiffness share the sequence), 1..N without gaps, and never
overwritten. A new version may carry ``If-Match`` with the ETag of the hand's latest version: if another version
was stored meanwhile the request fails with 412 and nothing is stored.
"""

from __future__ import annotations

import hashlib
from pathlib import PurePath
from typing import Annotated, Any, Literal

from fastapi import APIRouter, File, Form, Path, Query, Response, UploadFile
from fastapi.responses import JSONResponse
from starlette.concurrency import run_in_threadpool

from softsig_service import registry as repo
from softsig_service.api.deps import Ctx, IfMatchOptional, WriteAccess
from softsig_service.api.job_responses import accepted, capture_signature_version, stiffness_signature_version
from softsig_service.api.routes.common import SUBMIT_JOB, WRITE, problem, read_route, with_etag
from softsig_service.api.routes.paging import DEFAULT_LIMIT, Limit, Offset, page_of
from softsig_service.api.schemas import (
    CRITERION_DESCRIPTION,
    HAND_NAME_PATTERN,
    CaptureSignatureIn,
    ClosureCriterion,
    ClosureSignatureIn,
    CsMethod,
    SignatureList,
    SignatureOut,
    StiffnessSignatureIn,
)
from softsig_service.errors import InvalidTrajectory
from softsig_service.services.serialize import vectors_as_objects
from softsig_service.services.tasks import closure_signature, markers_signature

router = APIRouter(prefix="/v1", tags=["signatures"])
HandPath = Annotated[str, Path(pattern=HAND_NAME_PATTERN, description="the hand's name")]
KindQuery = Annotated[
    Literal["closure", "stiffness", "capture", "outcomes"] | None, Query(description="only this kind")
]


def signature_summary(rec: repo.SignatureRecord) -> dict[str, Any]:
    """The JSON of :class:`SignatureSummary`."""
    return {
        "hand": rec.hand,
        "version": rec.version,
        "kind": rec.kind,
        "cs_method": rec.method if rec.kind == "closure" else None,
        "cs_criterion": rec.criterion,
        "object": rec.method if rec.kind in ("stiffness", "capture") else None,
        "source": rec.source,
        "hand_revision": rec.hand_revision,
        "etag": rec.etag,
        "created_at": rec.created_at,
        "links": {"self": f"/v1/hands/{rec.hand}/signatures/{rec.version}"},
    }


def signature_out(rec: repo.SignatureRecord) -> dict[str, Any]:
    """The JSON of :class:`SignatureOut`."""
    return {**signature_summary(rec), "params": rec.params, "signature": vectors_as_objects(rec.data)}


def _criterion_param(method: str, criterion: str) -> dict[str, str]:
    """``{"criterion": ...}`` for the ellipsoid method (the only one that has a criterion), else nothing."""
    return {"criterion": criterion} if method == "ellipsoid" else {}


NEW_VERSION: dict[str, Any] = {
    "status_code": 201,
    "response_model": SignatureOut,
    "dependencies": [WriteAccess],
    "responses": {
        404: problem("unknown hand"),
        409: problem("the hand was replaced while the signature was computed"),
        412: problem("If-Match does not match the latest version's ETag"),
        **WRITE,
    },
}
"""What the routes that store a new signature version declare: 201 with the version, write access, 404/409/412."""


def created(response: Response, rec: repo.SignatureRecord) -> dict[str, Any]:
    """A new version's 201 body, with its ``Location`` and ``ETag``."""
    response.headers["Location"] = f"/v1/hands/{rec.hand}/signatures/{rec.version}"
    return signature_out(with_etag(response, rec))


_SUBMIT_HAND_JOB: dict[str, Any] = {
    **SUBMIT_JOB,
    "responses": {404: problem("unknown hand"), **SUBMIT_JOB["responses"]},
}
"""A job submitted for one hand: :data:`SUBMIT_JOB` and 404 for an unknown hand."""


@router.post(
    "/hands/{hand}/signatures/closure",
    **NEW_VERSION,
    summary="Compute the closure signature from a simulated closure and store it as a new version",
)
async def create_closure_signature(
    ctx: Ctx, hand: HandPath, response: Response, if_match: IfMatchOptional, body: ClosureSignatureIn
) -> dict[str, Any]:
    """``{"cs_method": "ellipsoid"|"pca"|"mesh", "cs_criterion": "absolute"|"relative"}``: simulate the hand's
    free closure (in a worker process) and compute its closure signature (hand frame); the criterion (ellipsoid
    only, default "absolute": deltas in metres) is stored in ``params``. 201 with the stored version,
    ``Location`` and ``ETag``."""
    record = await run_in_threadpool(ctx.hand, hand)
    result = await ctx.pool.run(
        closure_signature, record.manifest_path, ctx.settings.limits, body.cs_method, body.cs_criterion,
        what="simulating the closure", field="cs_method",
    )  # fmt: skip
    params = {
        "method": body.cs_method, **_criterion_param(body.cs_method, body.cs_criterion), "closure": result["closure"]
    }  # fmt: skip
    rec = await run_in_threadpool(
        lambda: repo.add_signature(
            ctx.registry, hand, kind="closure", method=body.cs_method, source="simulation", data=result["signature"],
            params=params, hand_revision=record.revision, if_match=if_match,
        )
    )  # fmt: skip
    return created(response, rec)


@router.post(
    "/hands/{hand}/signatures/stiffness",
    **_SUBMIT_HAND_JOB,
    summary="Compute the stiffness signature (a job); stored as a new version when it succeeds",
)
async def create_stiffness_signature(
    ctx: Ctx, hand: HandPath, if_match: IfMatchOptional, body: StiffnessSignatureIn
) -> JSONResponse:
    """``{"object": ...}``: grasp the object in MuJoCo and compute the 6x6 grasp stiffness and break forces, a long
    computation: 202 with the job (``Location: /v1/jobs/{id}``); the signature is stored as the hand's next
    version when the job succeeds (its result links to it). ``If-Match`` is checked when the version is
    stored."""
    record = await run_in_threadpool(ctx.hand, hand)
    job = await stiffness_signature_version(ctx, record, body, if_match)
    return accepted(job)


@router.post(
    "/hands/{hand}/signatures/capture",
    **_SUBMIT_HAND_JOB,
    summary="Compute the capture model of strategy R (a job); stored as a new version when it succeeds",
)
async def create_capture_signature(
    ctx: Ctx, hand: HandPath, if_match: IfMatchOptional, body: CaptureSignatureIn
) -> JSONResponse:
    """Grasp ``object`` in MuJoCo over a grid of relative poses (``n_theta`` yaws x offsets) plus held-out
    checks: the hand's capture model on this object, which strategy R plans with. 202 with the job; the model is
    stored as the hand's next version (kind ``capture``) when the job succeeds."""
    record = await run_in_threadpool(ctx.hand, hand)
    job = await capture_signature_version(ctx, record, body, if_match)
    return accepted(job)


@router.post(
    "/hands/{hand}/signatures/markers",
    **NEW_VERSION,
    summary="Upload tracked markers and store the closure signature computed from them",
)
async def upload_markers(
    ctx: Ctx,
    hand: HandPath,
    response: Response,
    if_match: IfMatchOptional,
    file: Annotated[UploadFile, File(description="CSV time,point,x,y,z [s, m, hand frame] or trajectory JSON")],
    cs_method: Annotated[CsMethod, Form()] = "ellipsoid",
    cs_criterion: Annotated[ClosureCriterion, Form(description=CRITERION_DESCRIPTION)] = "absolute",
    strict_points: Annotated[
        bool, Form(description="point names must be the hand's reference points (all of them)")
    ] = True,
) -> dict[str, Any]:
    """Compute the closure signature from tracked marker trajectories (hand frame [m]) and store it as a new
    version; ``cs_criterion`` (ellipsoid only, default "absolute") is stored in ``params``."""
    record = await run_in_threadpool(ctx.hand, hand)
    name = file.filename or ""
    suffix = PurePath(name).suffix.lower()
    ctype = (file.content_type or "").split(";")[0].strip().lower()
    fmt = "csv" if suffix == ".csv" or (not suffix and ctype == "text/csv") else None
    if fmt is None and (suffix == ".json" or (not suffix and ctype == "application/json")):
        fmt = "json"
    if fmt is None:
        raise InvalidTrajectory("marker files are .csv or .json", field="file", value=name, choices=[".csv", ".json"])
    raw = await file.read()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InvalidTrajectory("the marker file is not UTF-8 text", field="file", value=name) from None
    expected = [p.get("name") for p in record.info.get("reference_points", [])] if strict_points else None
    result = await ctx.pool.run(
        markers_signature, text, fmt, cs_method, expected, hand, cs_criterion,
        what="computing the signature from markers", field="file",
    )  # fmt: skip
    params = {
        "method": cs_method,
        **_criterion_param(cs_method, cs_criterion),
        "file": name,
        "sha256": hashlib.sha256(raw).hexdigest(),
        "strict_points": strict_points,
        "closure": result["closure"],
    }
    rec = await run_in_threadpool(
        lambda: repo.add_signature(
            ctx.registry, hand, kind="closure", method=cs_method, source="markers", data=result["signature"],
            params=params, hand_revision=record.revision, if_match=if_match,
        )
    )  # fmt: skip
    return created(response, rec)


@router.get(
    "/hands/{hand}/signatures", response_model=SignatureList, **read_route(), summary="List a hand's signature versions"
)
def list_signatures(ctx: Ctx, hand: HandPath, kind: KindQuery = None, limit: Limit = DEFAULT_LIMIT,
                    offset: Offset = 0) -> dict[str, Any]:  # fmt: skip
    """Versions, newest first (without the signature bodies)."""
    items, total = repo.list_signatures(ctx.registry, hand, kind=kind, limit=limit, offset=offset)
    return page_of([signature_summary(r) for r in items], total, limit, offset)


@router.get(
    "/hands/{hand}/signatures/latest",
    response_model=SignatureOut,
    **read_route(),
    summary="Get the latest signature version (of a kind)",
)
def latest_signature(ctx: Ctx, hand: HandPath, response: Response, kind: KindQuery = None) -> dict[str, Any]:
    """The newest version, of ``kind`` if given; 404 when there is none."""
    rec = repo.latest_signature(ctx.registry, hand, kind=kind)
    return signature_out(with_etag(response, rec))


@router.get(
    "/hands/{hand}/signatures/{version:int}",  # digits only: the literal routes beside it answer 405, not 422
    response_model=SignatureOut,
    **read_route(),
    summary="Get one signature version",
)
def get_signature(
    ctx: Ctx, hand: HandPath, version: Annotated[int, Path(ge=1, le=2**31 - 1)], response: Response
) -> dict[str, Any]:
    """One stored version (never changes once stored)."""
    rec = repo.get_signature(ctx.registry, hand, version)
    return signature_out(with_etag(response, rec))
