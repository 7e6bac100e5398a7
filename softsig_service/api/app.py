"""The REST service: ``create_app(settings)`` and its lifespan.

At startup the lifespan opens the registry (creating its tables), registers the built-in hands found in
``settings.hands_dir`` that are not registered yet, builds the planner once for the app (UR5 model, collision
worlds; with ``warm_planner`` also the planning models of the built-in hands), starts the compute pool and the job
manager, which claims queued jobs and those a dead process left (:mod:`softsig_service.services.jobs`). At
shutdown it kills its running jobs, hands them back to the queue and stops the worker processes.

Routes live under ``/v1`` (``routes/``); ``/healthz``, ``/readyz`` and ``/metrics`` at the root. Middleware, from
the outside in: request id + access log + metrics (``api/logging.py``), the API key and the body read timeout
(``api/guard.py``), then the body limits (``api/problems.py``).
``openapi/openapi.json`` is :func:`openapi_json` of an app with default settings; what of the document depends on
the settings is listed in :mod:`softsig_service.api.contract`.
"""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import AsyncIterator, Mapping
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool

from softsig_service import __version__
from softsig_service import registry as repo
from softsig_service.api.context import AppContext
from softsig_service.api.contract import add_body_models, apply_settings
from softsig_service.api.docs_page import install_docs
from softsig_service.api.guard import AuthGateMiddleware
from softsig_service.api.idempotency import IdempotencyMiddleware
from softsig_service.api.logging import RequestContextMiddleware
from softsig_service.api.object_schemas import ObjectIn
from softsig_service.api.problems import BodyLimitMiddleware, install_problem_handlers
from softsig_service.config import Settings
from softsig_service.registry.db import Registry
from softsig_service.registry.idempotency import purge_expired_keys
from softsig_service.services.compute import ComputePool
from softsig_service.services.job_kinds import default_job_kinds, object_digest_of, register_builtin_hands
from softsig_service.services.jobs import JobKind, JobManager
from softsig_service.services.observability import Metrics
from softsig_service.services.retention import purge_old, retention_loop

log = logging.getLogger("softsig.api")

UPLOAD_PATHS: tuple[str, ...] = (r"/v1/hands", r"/v1/hands/archive", r"/v1/hands/[^/]+", r"/v1/objects")
"""Paths that take multipart uploads of hands and object files (a multipart body to one: ``max_upload_bytes``)."""
SELF_READ_BODIES: tuple[type[BaseModel], ...] = (ObjectIn,)
"""The JSON bodies of routes that read their body themselves (:func:`~softsig_service.api.contract.add_body_models`)."""
MARKERS_PATH = r"/v1/hands/[^/]+/signatures/markers"
"""The marker upload (limit ``max_markers_bytes``)."""

DESCRIPTION = """\
softsig over HTTP: a versioned registry of hands and their closure and stiffness signatures, top-grasp planning
for a UR5, and validation jobs in MuJoCo.

* Units are SI (m, rad, s, kg, N). The world frame is the UR5 `base_link` (z up); poses carry `frame_id` and
  named quaternion fields `{x, y, z, w}`; signatures are in the hand frame (origin at the flange, +z the approach).
* Writes need `X-API-Key`; reads are open unless the service says otherwise.
* Errors are RFC 9457 `application/problem+json` naming the offending `field`.
* Updates and deletes of a hand need `If-Match` with its `ETag` (428 without, 412 on a mismatch).
* Long work (validations, experiments) answers `202 Accepted` with `Location: /v1/jobs/{id}`.
"""


def _startup(settings: Settings, registry: Registry) -> Any:
    """Blocking startup work (run in a thread): built-in hands, the planner and its warm-up."""
    from softsig_service.planning.planner import Planner, planning_model

    purge_expired_keys(registry)
    filled = repo.fill_object_digests(registry, object_digest_of)
    if filled:
        log.info("gave %d stored signatures their object's digest", filled)
    done = register_builtin_hands(registry, settings)
    added = [n for n, what in done.items() if what == "added"]
    if added:
        log.info("registered built-in hands: %s", ", ".join(added))
    planner = Planner(settings)
    if settings.warm_planner:
        for record in repo.list_hands(registry):
            if record.builtin:
                ref = repo.hand_ref(registry, record.name)
                planning_model(record.manifest_path, settings=settings, revision=ref.token)
    return planner


def create_app(settings: Settings | None = None, *, job_kinds: Mapping[str, JobKind] | None = None) -> FastAPI:
    """The FastAPI app of the service. ``job_kinds`` adds kinds of jobs to the default ones (tests)."""
    settings = settings or Settings()
    metrics = Metrics()
    kinds = {**default_job_kinds(), **(job_kinds or {})}

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        data_dir = settings.data_dir
        hands_dir, plans_dir, jobs_dir = data_dir / "hands", data_dir / "plans", data_dir / "jobs"
        for d in (hands_dir, plans_dir, jobs_dir):
            d.mkdir(parents=True, exist_ok=True)
        registry = await run_in_threadpool(
            lambda: Registry(settings.resolved_database_url(), busy_timeout=settings.db_busy_timeout)
        )
        pool = ComputePool(settings.compute_workers, settings.compute_timeout)
        jobs = JobManager(registry, settings, kinds, jobs_dir, metrics)
        purger: asyncio.Task[None] | None = None
        try:
            planner = await run_in_threadpool(_startup, settings, registry)
            await jobs.start()
            pool.warm()
            app.state.ctx = AppContext(
                settings=settings,
                registry=registry,
                planner=planner,
                pool=pool,
                jobs=jobs,
                metrics=metrics,
                api_keys=[k.get_secret_value() for k in settings.api_keys],
                hands_dir=hands_dir,
                plans_dir=plans_dir,
            )
            if settings.retention_days is not None:
                await run_in_threadpool(purge_old, registry, settings.retention_days, plans_dir, jobs_dir)
                purger = asyncio.create_task(
                    retention_loop(registry, settings.retention_days, settings.retention_interval, plans_dir, jobs_dir)
                )
            log.info("softsig service ready (registry %s)", registry.engine.url.render_as_string(hide_password=True))
            yield
        finally:
            if purger is not None:
                purger.cancel()
            await jobs.shutdown()
            pool.shutdown()
            registry.dispose()
            metrics.process_exited()

    app = FastAPI(
        docs_url=None,  # served from the package (docs_page), not from a CDN
        redoc_url=None,
        title="softsig",
        version=__version__,
        description=DESCRIPTION,
        lifespan=lifespan,
        openapi_tags=[
            {"name": "hands", "description": "the hand registry: built-in and uploaded hands"},
            {"name": "signatures", "description": "versioned closure and stiffness signatures of a hand"},
            {"name": "objects", "description": "registered objects: geometry sent once, named by id in plans"},
            {"name": "plans", "description": "top-grasp planning for the UR5 (strategies S and C)"},
            {"name": "jobs", "description": "validations and experiments in MuJoCo, run as jobs"},
            {"name": "calibration", "description": "real grasp outcomes, and calibration of a hand to them (a job)"},
            {"name": "operations", "description": "health, readiness and metrics"},
        ],
    )
    install_problem_handlers(app)
    install_docs(app)
    from softsig_service.api.routes import calibration, hands, jobs, objects, ops, plans, scenes, signatures

    # matched in this order, each router's routes in turn: the hot routes' routers first (no two routers' paths
    # overlap, so the order changes no match; the OpenAPI document's paths are sorted)
    routers = (ops.router, hands.router, plans.router, signatures.router, calibration.router, objects.router,
               scenes.router, jobs.router)  # fmt: skip
    for router in routers:
        app.include_router(router)
    templates = [route for router in routers for route in router.routes]
    app.state.routes = templates  # what a 405's Allow header lists (api/problems.py)
    # inside the body limit: a replayed request's body is counted too
    app.add_middleware(IdempotencyMiddleware, routes=templates)
    app.add_middleware(
        BodyLimitMiddleware,
        max_body_bytes=settings.max_body_bytes,
        max_upload_bytes=settings.max_upload_bytes,
        upload_paths=UPLOAD_PATHS,
        route_limits=((MARKERS_PATH, settings.max_markers_bytes),),
    )
    app.add_middleware(
        AuthGateMiddleware,
        api_keys=[k.get_secret_value() for k in settings.api_keys],
        read_auth=settings.read_auth,
        body_read_timeout=settings.body_read_timeout,
        body_deadline=settings.body_deadline,
    )
    app.add_middleware(RequestContextMiddleware, metrics=metrics, routes=templates)
    _document_settings(app, settings)
    return app


def _document_settings(app: FastAPI, settings: Settings) -> None:
    """``app.openapi()`` states what ``settings`` make the service enforce (:mod:`softsig_service.api.contract`)."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            app.openapi_schema = apply_settings(add_body_models(build(), SELF_READ_BODIES), settings)
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]


def service_app() -> FastAPI:
    """The app of one process of ``softsig serve --workers N``: settings from the environment, logging set up
    (uvicorn's factory; each worker process calls it). The process dies with uvicorn's supervisor, so that a
    ``kill -9`` of ``softsig serve`` leaves no worker serving or running jobs (their own children follow them)."""
    from softsig_service.api.logging import configure_logging
    from softsig_service.services.lifeline import die_with_parent

    die_with_parent()

    settings = Settings()
    configure_logging(settings.log_level)
    return create_app(settings)


def openapi_json(app: FastAPI | None = None) -> str:
    """The OpenAPI document of the app as committed in ``openapi/openapi.json`` (sorted keys, indent 2)."""
    app = app or create_app(Settings())
    return json.dumps(app.openapi(), sort_keys=True, indent=2, ensure_ascii=False) + "\n"
