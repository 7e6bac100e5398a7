"""``/v1/hands/{hand}/outcomes`` and ``/v1/calibrations``: real outcomes in, a calibrated variant of the hand out.

Real outcomes are stored as a version of the hand's signatures (kind ``outcomes``, source ``real``): numbered
with the hand's other versions, never overwritten, listed by ``GET /v1/hands/{hand}/signatures?kind=outcomes``.
A calibration is a job (docs/calibration.md); when it succeeds its calibrated variant is registered as a hand of
its own (the job result's ``variant``), usable wherever a hand is named.
"""

from __future__ import annotations

import uuid
from typing import Any

from fastapi import APIRouter, Response
from fastapi.responses import JSONResponse
from starlette.concurrency import run_in_threadpool

from softsig_service import registry as repo
from softsig_service.api.deps import Ctx, IfMatchOptional
from softsig_service.api.job_responses import accepted
from softsig_service.api.routes.common import SUBMIT_JOB, problem
from softsig_service.api.routes.jobs import hand_for_job, private_params, require_kind
from softsig_service.api.routes.signatures import NEW_VERSION, HandPath, created
from softsig_service.api.schemas import CalibrationIn
from softsig_service.errors import Conflict, InvalidInput, NotFound
from softsig_service.experiments.outcomes import RealOutcomes

router = APIRouter(prefix="/v1", tags=["calibration"])
OUTCOMES_KIND = "outcomes"


@router.post("/hands/{hand}/outcomes", **NEW_VERSION, summary="Upload real grasp outcomes of a hand")
async def upload_outcomes(
    ctx: Ctx, hand: HandPath, body: RealOutcomes, response: Response, if_match: IfMatchOptional
) -> dict[str, Any]:
    """Store real outcomes (per-cell counts and/or per-trial records, docs/calibration.md) as a new version of the
    hand (kind ``outcomes``); 422 naming the field for counts above trials, unknown objects or strategies, or a
    cell given twice."""
    record = await run_in_threadpool(ctx.hand, hand)
    counts = body.counts()
    params = {
        "cells": len(counts),
        "trials": sum(n for _, n in counts.values()),
        "successes": sum(k for k, _ in counts.values()),
        "note": body.note,
    }
    rec = await run_in_threadpool(
        lambda: repo.add_signature(
            ctx.registry,
            hand,
            kind=OUTCOMES_KIND,
            method="real",
            source="real",
            data=body.model_dump(mode="json"),
            params=params,
            hand_revision=record.revision,
            if_match=if_match,
        )
    )
    return created(response, rec)


def _outcomes_version(ctx: Any, hand: str, version: int | None) -> repo.SignatureRecord:
    if version is None:
        try:
            return repo.latest_signature(ctx.registry, hand, kind=OUTCOMES_KIND)
        except NotFound:
            raise InvalidInput(
                "the hand has no real outcomes: upload them first (POST /v1/hands/{hand}/outcomes)",
                field="outcomes_version",
            ) from None
    try:
        rec = repo.get_signature(ctx.registry, hand, version)
    except NotFound:
        raise InvalidInput("no such version of the hand", field="outcomes_version", value=version) from None
    if rec.kind != OUTCOMES_KIND:
        raise InvalidInput(
            f"version {version} is a {rec.kind} signature, not outcomes", field="outcomes_version", value=version
        )
    return rec


def _check(ctx: Any, body: CalibrationIn, hand_ref: str) -> tuple[dict[str, Any], dict[str, Any], int]:
    """The job's parameters, checked as the job will run them (422 naming the field), the outcomes it fits and
    its simulations."""
    from softsig_service.experiments.calibration import CalibrationSpec, planned_simulations

    rec = _outcomes_version(ctx, body.hand, body.outcomes_version)
    outcomes = RealOutcomes.model_validate(rec.data)
    name = body.name or f"{body.hand}_cal_{uuid.uuid4().hex[:8]}"[-64:]
    if name in repo.hand_names(ctx.registry):
        raise Conflict("a hand of this name is registered already", field="name", value=name)
    spec = CalibrationSpec(
        hand=hand_ref,
        outcomes=outcomes,
        held_out=tuple(body.held_out),
        parameters=tuple(body.parameters),
        ranges=dict(body.ranges),
        budget=body.budget,
        trials_per_cell=body.trials_per_cell,
        test_trials=body.test_trials,
        seed=body.seed,
        name=name,
        outcomes_version=rec.version,
    )
    sims = planned_simulations(spec)
    params = {
        "hand": body.hand,
        "outcomes_version": rec.version,
        "held_out": [s.model_dump(exclude_none=True) for s in body.held_out],
        "parameters": list(body.parameters),
        "ranges": {k: list(v) for k, v in body.ranges.items()},
        "budget": body.budget,
        "trials_per_cell": body.trials_per_cell,
        "test_trials": body.test_trials,
        "seed": body.seed,
        "name": name,
        "workers": body.workers,
    }
    return params, rec.data, sims


@router.post(
    "/calibrations",
    **{**SUBMIT_JOB, "responses": {409: problem("the variant's name is taken"), **SUBMIT_JOB["responses"]}},
    summary="Calibrate a hand to its real outcomes (a job)",
)
async def create_calibration(ctx: Ctx, body: CalibrationIn) -> JSONResponse:
    """Fit the hand's declared parameters (its manifest's ``[calibration]``) to the stored real outcomes not held
    out, then predict the held-out cells with the calibrated and the uncalibrated model. 202 with the job; when it
    succeeds the result has the parameters found, the held-out log-likelihoods (calibrated, uncalibrated,
    constant rate) and ``variant`` (the calibrated hand, registered); files ``calibration.json``, ``report.md``,
    ``calibration.png``, ``evaluations.jsonl``."""
    require_kind(ctx, "calibration")
    hand = await run_in_threadpool(hand_for_job, ctx, body.hand)
    private = private_params(ctx, hand)
    params, outcomes, sims = await run_in_threadpool(_check, ctx, body, private["hand_ref"])
    cap = ctx.settings.max_job_trials
    if sims > cap:
        raise InvalidInput(
            f"the calibration asks for {sims} simulations; the service allows at most {cap}",
            field="budget",
            value=body.budget,
        )
    private.update(user_hands_dir=str(ctx.hands_dir), outcomes=outcomes)
    job = await ctx.jobs.submit("calibration", params, body.time_limit, private=private)
    return accepted(job)
