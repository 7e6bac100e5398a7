"""Operations: liveness, readiness and Prometheus metrics (no API key needed)."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response
from prometheus_client import CONTENT_TYPE_LATEST
from starlette.concurrency import run_in_threadpool

from softsig_service.api.problems import problem_body, problem_response
from softsig_service.api.responses import json_response, model_json
from softsig_service.api.routes.common import COMMON
from softsig_service.api.schemas import Health, Readiness

router = APIRouter(tags=["operations"], responses=COMMON)


@router.get("/healthz", response_model=Health, summary="Liveness: the process serves requests")
async def healthz() -> Response:
    """Always ``{"status": "ok"}`` while the process can answer."""
    return json_response(HEALTHY)  # the bytes made once (api/responses.py)


HEALTHY = model_json(Health, {"status": "ok"})
"""``/healthz``'s body."""


@router.get(
    "/readyz",
    response_model=Readiness,
    summary="Readiness: registry reachable, built-in hands registered, workers available",
    responses={503: {"model": Readiness, "description": "not ready: the failing checks say why"}},
)
async def readyz(request: Request) -> Response | Readiness:
    """``ready`` when the registry answers and the service finished starting, else 503 with the reasons."""
    ctx = getattr(request.app.state, "ctx", None)
    if ctx is None:
        body = problem_body(503, slug="not-ready", detail="the service is starting", instance="/readyz")
        return problem_response(503, body)
    checks = {
        "registry": "ok" if await run_in_threadpool(ctx.registry.ping) else "the database does not answer",
        "compute_pool": "ok" if ctx.pool.alive else "restarting",
    }
    ready = all(v == "ok" for v in checks.values())
    result = Readiness(status="ready" if ready else "not_ready", checks=checks)
    if not ready:
        return Response(result.model_dump_json(), status_code=503, media_type="application/json")
    return result


@router.get(
    "/metrics",
    summary="Prometheus metrics (text exposition format)",
    response_class=Response,
    responses={200: {"content": {"text/plain": {}}, "description": "metrics"}},
)
async def metrics(request: Request) -> Response:
    """Request counts and latency histograms by route template, planner time, jobs."""
    ctx = request.app.state.ctx
    return Response(ctx.metrics.exposition(), media_type=CONTENT_TYPE_LATEST)
