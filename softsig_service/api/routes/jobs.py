"""``/v1/jobs``, ``/v1/validations``, ``/v1/experiments``: long work run as jobs in worker processes.

Submitting answers ``202 Accepted`` with ``Location: /v1/jobs/{id}``; ``GET /v1/jobs/{id}`` gives status,
progress and (when done) the result; ``DELETE /v1/jobs/{id}`` cancels a queued or running job (its processes are
killed); ``GET /v1/jobs/{id}/files`` lists the result files (JSON, CSV, Markdown, PNG...) and
``GET /v1/jobs/{id}/files/{name}`` downloads one.

Job kinds (``kind`` of a job): ``stiffness_signature`` (``POST /v1/hands/{hand}/signatures`` with
``{"kind": "stiffness"}``; the signature is stored as a new version when the job succeeds), ``validation``
(``POST /v1/validations``) and ``experiment`` (``POST /v1/experiments``). Caps: ``max_job_trials`` trials per job
(an experiment has 18 cells: at most ``max_job_trials // 18`` per cell, as its schema states), ``max_job_seconds``
of wall time.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Path, Query
from fastapi.responses import FileResponse, JSONResponse
from starlette.concurrency import run_in_threadpool

from softsig_service import registry as repo
from softsig_service.api.context import AppContext
from softsig_service.api.deps import Ctx
from softsig_service.api.job_responses import accepted, job_out
from softsig_service.api.routes.common import SUBMIT_JOB, problem, read_route, write_route
from softsig_service.api.routes.paging import DEFAULT_LIMIT, Limit, Offset, page, page_of
from softsig_service.api.scene import scene_objects, stored_objects
from softsig_service.api.schemas import ExperimentIn, JobFiles, JobList, JobOut, ValidationIn
from softsig_service.errors import HandNotFound, InvalidInput, NotAvailable, NotFound, RenderUnavailable
from softsig_service.experiments.campaign_spec import TABLE1_CELLS
from softsig_service.gl_backend import render_unavailable_reason
from softsig_service.objects.schema import object_json
from softsig_service.services.job_files import MEDIA_TYPES, list_files, media_type, resolve_file
from softsig_service.services.tasks import model_settings

router = APIRouter(prefix="/v1", tags=["jobs"])
JobId = Annotated[str, Path(pattern=r"^[0-9a-f]{32}$", description="a job's id")]


def hand_for_job(ctx: AppContext, name: str) -> repo.HandRecord:
    try:
        return ctx.hand(name)
    except HandNotFound as exc:
        raise InvalidInput("unknown hand", field="hand", value=name, choices=exc.choices) from None


def _hand_ref(hand: repo.HandRecord) -> str:
    """How a worker names the hand: built-in hands by name, uploaded ones by their manifest path."""
    return hand.name if hand.builtin else hand.manifest_path


def private_params(ctx: AppContext, hand: repo.HandRecord) -> dict[str, Any]:
    """A simulation job's private parameters: how it finds the hand, and the settings that shape its models."""
    return {"hand_ref": _hand_ref(hand), "settings": model_settings(ctx.settings)}


def _check_trials(ctx: AppContext, n: int, what: str) -> None:
    cap = ctx.settings.max_job_trials
    if n > cap:
        raise InvalidInput(f"{what} asks for {n} trials; the service allows at most {cap}", field="trials", value=n)


def require_kind(ctx: AppContext, kind: str) -> None:
    if kind not in ctx.jobs.kinds:
        raise NotAvailable(f"{kind} jobs are not offered by this service", field="kind", value=kind)


@router.post(
    "/validations",
    **SUBMIT_JOB,
    summary="Validate a grasp in MuJoCo (a job)",
)
async def create_validation(ctx: Ctx, body: ValidationIn) -> JSONResponse:
    """Plan the grasp of ``object`` on its nominal pose and simulate ``trials`` rollouts with the object
    perturbed (docs/design.md §7). 202 with the job and ``Location: /v1/jobs/{id}``; its result has ``trials``,
    ``successes`` and ``outcomes`` (one ``{seed, success, reason, lift_height}`` per trial); files
    ``validation.json`` and ``outcomes.csv``, and with ``keyframes`` one strip per trial,
    ``keyframes/trial_NNN.png``, whose URLs the result's ``keyframes`` lists."""
    require_kind(ctx, "validation")
    _check_trials(ctx, body.trials, "the validation")
    hand = await run_in_threadpool(hand_for_job, ctx, body.hand)
    # bad objects fail now, naming the field; the job gets them in base_link (a cloud as its solid; a tabletop's
    # other clusters as obstacles)
    parsed, obstacles = await run_in_threadpool(scene_objects, body.object, body.obstacles, body, stored_objects(ctx))
    obj = object_json(body.object) if body.object.kind == "builtin" and not body.frames else parsed.to_json()
    params = {
        "hand": hand.name, "object": obj, "table_height": parsed.table_height, "strategy": body.strategy,
        "sigma_r": body.sigma_r, "sigma_t": body.sigma_t, "trials": body.trials, "seed": body.seed,
    }  # fmt: skip
    if obstacles:
        params["obstacles"] = [o.to_json() for o in obstacles]
    if body.keyframes:
        reason = render_unavailable_reason()
        if reason is not None:
            raise RenderUnavailable(f"keyframes need offscreen rendering, which this service lacks: {reason}",
                                    field="keyframes", value=True)  # fmt: skip
        params["keyframes"] = True
    job = await ctx.jobs.submit("validation", params, body.time_limit, private=private_params(ctx, hand))
    return accepted(job)


@router.post(
    "/experiments",
    **SUBMIT_JOB,
    summary="Run the reference experiment, Table I (a job)",
)
async def create_experiment(ctx: Ctx, body: ExperimentIn) -> JSONResponse:
    """The paper's Table I in simulation: 3 conditions x 3 objects x strategies S and C x ``trials`` per cell.
    202 with the job; when done its files are ``report.md`` (Table I layout, Wilson intervals, Fisher tests),
    ``results.json``, ``results.csv``, ``table1.png``, ``trials.jsonl`` and ``campaign.json``."""
    require_kind(ctx, "experiment")
    _check_trials(ctx, TABLE1_CELLS * body.trials, f"the experiment ({TABLE1_CELLS} cells)")
    hand = await run_in_threadpool(hand_for_job, ctx, body.hand)
    params = {"name": body.name, "hand": hand.name, "trials": body.trials, "seed": body.seed, "workers": body.workers}
    job = await ctx.jobs.submit("experiment", params, body.time_limit, private=private_params(ctx, hand))
    return accepted(job)


@router.get("/jobs", response_model=JobList, **read_route(), summary="List jobs")
def list_jobs(
    ctx: Ctx,
    kind: Annotated[str | None, Query(max_length=32, description="only jobs of this kind")] = None,
    status: Annotated[
        Literal["queued", "running", "succeeded", "failed", "cancelled", "timed_out"] | None,
        Query(description="only jobs in this status"),
    ] = None,
    limit: Limit = DEFAULT_LIMIT,
    offset: Offset = 0,
) -> dict[str, Any]:
    """Jobs, newest first."""
    items, total = repo.list_jobs(ctx.registry, kind=kind, status=status, limit=limit, offset=offset)
    return page_of([job_out(r) for r in items], total, limit, offset)


@router.get("/jobs/{job_id}", response_model=JobOut, **read_route(), summary="Get a job")
def get_job(ctx: Ctx, job_id: JobId) -> dict[str, Any]:
    """Status, progress in [0, 1], and the result or the error when finished."""
    return job_out(repo.get_job(ctx.registry, job_id))


@router.post(
    "/jobs/{job_id}/cancel",
    status_code=202,
    response_model=JobOut,
    **write_route({409: problem("the job has finished already"), 404: problem("no such job")}),
    summary="Cancel a job",
)
async def cancel_job(ctx: Ctx, job_id: JobId) -> dict[str, Any]:
    """Cancel a queued or running job: 202, and the job becomes ``cancelled`` (its processes are killed)."""
    return job_out(await ctx.jobs.cancel(job_id))


@router.get("/jobs/{job_id}/files", response_model=JobFiles, **read_route(), summary="List a job's result files")
def job_files(ctx: Ctx, job_id: JobId, limit: Limit = DEFAULT_LIMIT, offset: Offset = 0) -> dict[str, Any]:
    """The files the job wrote (JSON, CSV, Markdown, PNG...), by name, with sizes [bytes] and download URLs."""
    repo.get_job(ctx.registry, job_id)
    items = [
        {"name": name, "size": size, "media_type": media_type(name), "url": f"/v1/jobs/{job_id}/files/{name}"}
        for name, size in list_files(ctx.jobs.out_dir(job_id))
    ]
    return page(items, limit, offset)


FILE_CONTENT = {
    media: {"schema": {"type": "string", "format": "binary"}}
    for media in sorted({*MEDIA_TYPES.values(), "application/octet-stream"})
}
"""The media types a result file is served in (by its suffix, :data:`MEDIA_TYPES`; others as octet-stream)."""


@router.get(
    "/jobs/{job_id}/files/{name:path}",
    response_class=FileResponse,
    **read_route({200: {"description": "the file, in the media type of its suffix", "content": FILE_CONTENT}}),
    summary="Download a job's result file",
)
async def job_file(ctx: Ctx, job_id: JobId, name: str) -> FileResponse:
    """One result file, with its media type."""
    await run_in_threadpool(repo.get_job, ctx.registry, job_id)
    path = resolve_file(ctx.jobs.out_dir(job_id), name)
    if path is None:
        raise NotFound("no such result file", field="name", value=name)
    return FileResponse(path, media_type=media_type(name), filename=path.name)
