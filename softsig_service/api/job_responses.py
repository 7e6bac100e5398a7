"""What the job routes answer: a job's JSON, ``202 Accepted`` with its location, and the submission of a
stiffness-signature or capture-model job (shared by ``/v1/jobs`` and the signature routes, so that no route
imports another).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from fastapi.responses import JSONResponse

from softsig_service import registry as repo
from softsig_service.api.context import AppContext
from softsig_service.api.schemas import CaptureSignatureIn, JobOut, StiffnessSignatureIn
from softsig_service.errors import InvalidInput
from softsig_service.objects.schema import object_json
from softsig_service.services.tasks import model_settings


def job_out(rec: repo.JobRecord) -> dict[str, Any]:
    """The JSON of :class:`JobOut`."""
    return {
        "id": rec.id,
        "kind": rec.kind,
        "status": rec.status,
        "progress": rec.progress,
        "message": rec.message,
        "params": rec.params,
        "result": rec.result,
        "error": rec.error,
        "time_limit": rec.time_limit,
        "cancel_requested": rec.cancel_requested,
        "attempts": rec.attempts,
        "created_at": rec.created_at,
        "started_at": rec.started_at,
        "finished_at": rec.finished_at,
        "links": {"self": f"/v1/jobs/{rec.id}", "files": f"/v1/jobs/{rec.id}/files"},
    }


def accepted(rec: repo.JobRecord) -> JSONResponse:
    """``202 Accepted`` with ``Location: /v1/jobs/{id}`` and the job."""
    body = JobOut.model_validate(job_out(rec)).model_dump(mode="json")
    return JSONResponse(body, status_code=202, headers={"Location": f"/v1/jobs/{rec.id}"})


async def capture_signature_version(
    ctx: AppContext, hand: repo.HandRecord, body: CaptureSignatureIn, if_match: str | None
) -> repo.JobRecord:
    """Submit the capture-model job of ``hand`` (stored as a new version when it succeeds); bad grids and objects
    are refused now, naming the field."""
    from softsig_service.experiments.capture import CaptureGrid
    from softsig_service.objects import object_from_json

    grid = body.model_dump(include={f.name for f in dataclasses.fields(CaptureGrid)})
    n = CaptureGrid(**grid).simulations
    obj = object_json(body.object)
    object_from_json(obj)
    if n > ctx.settings.max_job_trials:
        raise InvalidInput(
            f"the capture model asks for {n} simulations; the service allows at most {ctx.settings.max_job_trials}",
            field="n_theta", value=n,
        )  # fmt: skip
    params: dict[str, Any] = {"hand": hand.name, "object": obj, "grid": grid, "hand_revision": hand.revision}
    if if_match is not None:
        params["if_match"] = if_match
    private = {"hand_ref": hand.manifest_path, "workers": ctx.settings.job_workers,
               "settings": model_settings(ctx.settings)}  # fmt: skip
    return await ctx.jobs.submit("capture_signature", params, private=private)


async def stiffness_signature_version(
    ctx: AppContext, hand: repo.HandRecord, body: StiffnessSignatureIn, if_match: str | None
) -> repo.JobRecord:
    """Submit the stiffness-signature job of ``hand`` (stored as a new version when it succeeds); an object that
    cannot be grasped is refused now, naming the field."""
    from softsig_service.objects import object_from_json
    from softsig_service.simulation.stiffness_signature import check_graspable

    obj = object_json(body.object)
    check_graspable(object_from_json(obj))
    params = {"hand": hand.name, "object": obj, "hand_revision": hand.revision}
    if if_match is not None:
        params["if_match"] = if_match
    private = {"manifest_path": hand.manifest_path, "limits": ctx.settings.limits.model_dump()}
    return await ctx.jobs.submit("stiffness_signature", params, private=private)
