"""``/v1/plans``: plan a UR5 top grasp (synchronous), get a stored plan, draw it.

Planning is CPU-bound but fast (milliseconds): it runs in the threadpool, never in the event loop, and at most
``Settings.plan_concurrency`` plans at a time per process (default 1: CPython runs one thread's Python at a time,
so more threads only add hand-offs of its lock, which also stretch the registry's write transactions; the
service's processes are what plan in parallel). The app's one :class:`~softsig_service.planning.planner.Planner`
keeps its models and solvers between requests and is safe to call from several threads. An infeasible request
is not an error: the plan has ``success: false`` and machine-readable ``reasons``.
"""

from __future__ import annotations

import json
import os
import threading
import uuid
from collections.abc import Callable
from pathlib import Path as FsPath
from typing import Annotated, Any

from fastapi import APIRouter, Path, Query, Request, Response
from starlette.concurrency import run_in_threadpool

from softsig_service import registry as repo
from softsig_service.api.context import AppContext
from softsig_service.api.deps import Ctx
from softsig_service.api.plan_schemas import PlanIn, PlanList, PlanOut
from softsig_service.api.responses import Answer, AnswerCache, json_response, model_json
from softsig_service.api.routes.common import problem, read_route, write_route
from softsig_service.api.routes.paging import DEFAULT_LIMIT, Limit, Offset, page_of
from softsig_service.api.scene import scene_frames, scene_objects, stored_objects
from softsig_service.api.schemas import HAND_NAME_PATTERN
from softsig_service.config import Settings
from softsig_service.errors import HandNotFound, InvalidInput, NotFound
from softsig_service.objects import TableObject
from softsig_service.services.plan_image import render_plan_png
from softsig_service.services.serialize import api_json
from softsig_service.signatures.capture import CaptureModel
from softsig_service.signatures.closure_types import Criterion

router = APIRouter(prefix="/v1", tags=["plans"])
PlanId = Annotated[str, Path(pattern=r"^[0-9a-f]{32}$", description="a stored plan's id")]


def _links(plan_id: str) -> dict[str, str]:
    return {"self": f"/v1/plans/{plan_id}", "image": f"/v1/plans/{plan_id}/image.png"}


def _plan_hand(ctx: AppContext, body: PlanIn) -> repo.HandRef:
    """The hand ``body`` names, as the registry holds it now (another process may have replaced it)."""
    try:
        return repo.hand_ref(ctx.registry, body.hand)
    except HandNotFound as exc:
        raise InvalidInput("unknown hand", field="hand", value=body.hand, choices=exc.choices) from None


def _model_key(ctx: AppContext, hand: repo.HandRef, body: PlanIn) -> tuple[str, str, Settings, Criterion, str]:
    """The arguments that name the hand's planning model for ``body`` (manifest, CS method, the service's settings,
    criterion, the hand's revision token), the same the app's planner asks for."""
    return (hand.manifest_path, body.cs_method, ctx.settings, body.cs_criterion, hand.token)


async def _build_planning_model(ctx: AppContext, hand: repo.HandRef, body: PlanIn) -> None:
    """Build the hand's planning model (it simulates the hand's closure) in the compute pool, under its time
    limit; never in the request's thread."""
    from softsig_service.planning import build_planning_model, remember_planning_model

    key = _model_key(ctx, hand, body)
    model = await ctx.pool.run(
        build_planning_model, *key[:4], what="building the hand's planning model (its closure)", field="hand"
    )
    remember_planning_model(model, *key)


PlanAnswer = tuple[str | None, bytes]
"""A plan's answer: its stored id (None: not stored) and its JSON body (``PlanOut``)."""


def _plan_if_ready(ctx: AppContext, body: PlanIn) -> tuple[repo.HandRef, PlanAnswer | None]:
    """The hand of ``body`` and, when this process has its planning model already, the plan's answer (one trip to
    the threadpool for both); None when the model must be built first."""
    from softsig_service.planning import cached_planning_model

    hand = _plan_hand(ctx, body)
    if cached_planning_model(*_model_key(ctx, hand, body)) is None:
        return hand, None
    return hand, _answer(ctx, body, hand)


def _answer(ctx: AppContext, body: PlanIn, hand: repo.HandRef) -> PlanAnswer:
    """:func:`make_plan`'s plan validated as ``PlanOut`` and serialised in one pass (what FastAPI would do with the
    returned dict, without its second pass through Python objects and ``json.dumps``)."""
    data = make_plan(ctx, body, hand)
    return data.get("id"), model_json(PlanOut, data)


def capture_model(
    ctx: AppContext, hand: repo.HandRef, obj: TableObject, version: int | None, *, required: bool = True
) -> CaptureModel | None:
    """The capture model strategy R plans with: signature ``version`` of ``hand``, which must be a capture model of
    an object of the shape, size, mass and friction of ``obj`` (its shape digest) computed on the hand's current
    revision; else the newest such one, found by one indexed query; else the model shipped in the hand's folder
    for such an object (as the CLI does); the model's JSON is read and parsed once per process and version.
    :class:`InvalidInput` naming ``capture_version`` when there is none, or only models of older revisions of the
    hand; with ``required`` false, None instead when no version was asked for and there is none."""
    from softsig_service.experiments.capture import shipped_capture_for

    digest = obj.shape_digest
    key: str
    source: Callable[[], dict[str, Any]]  # the model's JSON, read only when this process has not kept it
    if version is not None:
        try:
            rec = repo.get_signature(ctx.registry, hand.name, version)
        except NotFound:
            raise InvalidInput("no such signature version", field="capture_version", value=version) from None
        if rec.kind != "capture" or rec.object_digest != digest:
            raise InvalidInput(
                "not a capture model of this object (shape, size, mass and friction must match)",
                field="capture_version", value=version,
            )  # fmt: skip
        if rec.hand_revision != hand.revision:
            raise InvalidInput(
                f"capture model {version} was computed on revision {rec.hand_revision} of the hand, which is at "
                f"revision {hand.revision} now: POST /v1/hands/{hand.name}/signatures/capture again",
                field="capture_version", value=version,
            )  # fmt: skip
        key, data = rec.etag, rec.data
        source = lambda: data  # noqa: E731
    elif (newest := repo.newest_of_object(ctx.registry, hand.name, "capture", digest)) is not None:
        newest_version, key = newest  # a version's ETag names its content (hand, version, incarnation)
        source = lambda: repo.get_signature(ctx.registry, hand.name, newest_version).data  # noqa: E731
    elif (shipped := shipped_capture_for(FsPath(hand.manifest_path).parent, obj)) is not None:
        key = f"{hand.token}:{shipped.name}:{shipped.stat().st_mtime_ns}"
        source = lambda: json.loads(shipped.read_text(encoding="utf-8"))  # noqa: E731
    elif not required:
        return None
    else:  # none: which revisions have one says what to do (or one was stored meanwhile)
        found, stale = repo.signature_of_object(ctx.registry, hand.name, "capture", digest)
        if found is not None:
            key, found_data = found.etag, found.data
            source = lambda: found_data  # noqa: E731
        elif stale:
            raise InvalidInput(
                f"the hand's capture models of this object were computed on its revisions {stale}, not on its "
                f"current revision {hand.revision}: POST /v1/hands/{hand.name}/signatures/capture again",
                field="capture_version",
            )  # fmt: skip
        else:
            raise InvalidInput(
                "strategy R needs the hand's capture model on this object: POST "
                f"/v1/hands/{hand.name}/signatures/capture with it first", field="capture_version",
            )  # fmt: skip
    with _CAPTURES_LOCK:  # plans run in many threads
        model = _CAPTURES.get(key)
    if model is None:
        model = CaptureModel.from_json_dict(source())
        with _CAPTURES_LOCK:
            _CAPTURES[key] = model
            while len(_CAPTURES) > CAPTURES_KEPT:
                del _CAPTURES[next(iter(_CAPTURES))]
    return model


CAPTURES_KEPT = 32
"""Capture models a process keeps (the oldest read first out); each also keeps its noise averages."""
_CAPTURES: dict[str, CaptureModel] = {}
_CAPTURES_LOCK = threading.Lock()


PLANNER_FIELDS = (
    "strategy", "sigma_r", "sigma_t", "current_q", "closing_axis", "approach_distance", "margin", "cs_method",
    "cs_criterion", "placement", "candidates", "approach_cone",
)  # fmt: skip
"""The fields of a plan request (``PlanIn``) that reach the planner (``PlanRequest``) as they are, by the same
name. The others are resolved by the route first: ``hand`` (the registry's manifest and revision), ``object`` (parsed
over ``table`` in the ``frames`` given),
``capture_version`` (the capture model), or are the route's own (``store``); ``tests/api/test_api_contract.py``
keeps the two lists complete and apart."""
ROUTE_FIELDS = ("hand", "object", "capture_version", "store", "frames", "table", "obstacles", "output_frame")
"""The fields of ``PlanIn`` the route resolves or keeps for itself (see :data:`PLANNER_FIELDS`)."""


def make_plan(ctx: AppContext, body: PlanIn, hand: repo.HandRef) -> dict[str, Any]:
    """Plan ``body`` for the registered ``hand`` with the app's planner and store it (unless ``store`` is false);
    the plan JSON."""
    from softsig_service.objects.frames import output_frame_pose
    from softsig_service.planning.request import PlanRequest

    obj, obstacles = scene_objects(body.object, body.obstacles, body, stored_objects(ctx))
    frame = output_frame_pose(body.output_frame, scene_frames(body), obj.pose)
    # R plans with the hand's capture model of the object; S and C rate their grasps with it where there is one
    capture = capture_model(ctx, hand, obj, body.capture_version, required=body.strategy == "R")
    options = body.model_dump(include=set(PLANNER_FIELDS))
    request = PlanRequest(
        hand=hand.manifest_path, obj=obj, capture=capture, hand_revision=hand.token, obstacles=obstacles, **options
    )
    plan = ctx.planner.plan(request)  # thread-safe: per-thread solvers and collision worlds, no lock
    ctx.metrics.plan_seconds.labels(body.strategy).observe(plan.timing.get("total", 0.0))
    data: dict[str, Any] = api_json(plan.to_json_dict(body.output_frame, frame))
    data["hand_revision"] = hand.revision
    if body.store:
        rec = repo.add_plan(
            ctx.registry, hand=plan.hand, strategy=plan.strategy, success=plan.success,
            request=body.model_dump(mode="json"), result=data,
        )  # fmt: skip
        data.update(id=rec.id, created_at=rec.created_at, links=_links(rec.id))
    return data


def _plan_out(rec: repo.PlanRecord) -> dict[str, Any]:
    return {**rec.result, "id": rec.id, "created_at": rec.created_at, "links": _links(rec.id)}


@router.post(
    "/plans",
    status_code=201,
    response_model=PlanOut,
    **write_route({200: {"model": PlanOut, "description": "the plan, not stored (store: false)"}}),
    summary="Plan a top grasp (synchronous)",
)
async def create_plan(ctx: Ctx, body: PlanIn) -> Response:
    """Plan a UR5 top grasp of an object with strategy S, C or R; the plan (``success`` may be false, with
    ``reasons``): 201 with ``Location`` when stored, 200 with ``store: false`` (nothing is created)."""
    async with ctx.plan_slots:  # this process's turn to plan (Settings.plan_concurrency)
        hand, answer = await run_in_threadpool(_plan_if_ready, ctx, body)
    if answer is None:
        await _build_planning_model(ctx, hand, body)  # in the compute pool, without holding a turn
        async with ctx.plan_slots:
            answer = await run_in_threadpool(_answer, ctx, body, hand)
    plan_id, content = answer
    if plan_id:
        return json_response(content, 201, {"Location": f"/v1/plans/{plan_id}"})
    return json_response(content, 200)


@router.get("/plans", response_model=PlanList, **read_route(), summary="List plans")
def list_plans(
    ctx: Ctx,
    hand: Annotated[str | None, Query(pattern=HAND_NAME_PATTERN, description="only plans of this hand")] = None,
    limit: Limit = DEFAULT_LIMIT,
    offset: Offset = 0,
) -> dict[str, Any]:
    """Stored plans, newest first."""
    items, total = repo.list_plans(ctx.registry, hand=hand, limit=limit, offset=offset)
    rows = [
        {"id": r.id, "hand": r.hand, "strategy": r.strategy, "success": r.success, "created_at": r.created_at,
         "links": _links(r.id)}
        for r in items
    ]  # fmt: skip
    return page_of(rows, total, limit, offset)


@router.get("/plans/{plan_id}", response_model=PlanOut, **read_route(), summary="Get a plan")
async def get_plan(plan_id: PlanId, request: Request) -> Response:
    """A stored plan."""
    ctx: AppContext = request.app.state.ctx  # not the Ctx dependency: one level less to solve on a hot read
    stamp = repo.plan_stamp(ctx.registry, plan_id)  # one indexed row, on the loop (api/responses.py)
    if stamp is None:
        raise NotFound("no such plan", field="plan_id", value=plan_id)

    def make() -> tuple[Any, Answer]:
        rec = repo.get_plan(ctx.registry, plan_id)
        return (rec.id, rec.created_at), ("", model_json(PlanOut, _plan_out(rec)))

    return json_response((await PLAN_ANSWERS.aget((plan_id, stamp), make))[1])


PLAN_ANSWERS = AnswerCache(32 << 20)
"""``GET /v1/plans/{id}``'s answers by ``(id, created_at)`` (a stored plan never changes), 32 MiB at most."""


@router.delete(
    "/plans/{plan_id}",
    status_code=204,
    response_class=Response,
    **write_route(),
    summary="Delete a stored plan and its image",
)
def delete_plan(ctx: Ctx, plan_id: PlanId) -> Response:
    """Remove a stored plan and its cached image; 404 if there is none."""
    repo.delete_plan(ctx.registry, plan_id)
    (ctx.plans_dir / f"{plan_id}.png").unlink(missing_ok=True)
    return Response(status_code=204)


@router.get(
    "/plans/{plan_id}/image.png",
    response_class=Response,
    **read_route(
        {200: {"content": {"image/png": {}}, "description": "top view of the plan (PNG)"}, 404: problem("no such plan")}
    ),
    summary="Draw a plan (top view, PNG)",
)
async def plan_image(ctx: Ctx, plan_id: PlanId) -> Response:
    """A top view in the world x-y plane [m]: object footprint and axes, the open hand's reference points at the
    grasp pose, flange axes, the closure signature's axis, the pre-grasp. Drawn once, then cached."""
    path = ctx.plans_dir / f"{plan_id}.png"
    if not path.is_file():
        rec = await run_in_threadpool(repo.get_plan, ctx.registry, plan_id)
        manifest: str | None = None
        token = ""
        try:
            hand = await run_in_threadpool(ctx.hand, rec.hand)
            # the hand as it was planned with: the same revision of the same incarnation (one created before the
            # plan; a hand deleted and re-created since counts its revisions anew)
            if hand.revision == rec.result.get("hand_revision") and hand.created_at <= rec.created_at:
                manifest, token = hand.manifest_path, hand.token
        except HandNotFound:
            pass
        png = await ctx.pool.run(
            render_plan_png, rec.result, manifest, ctx.settings, token, what="drawing the plan", field="plan_id"
        )
        tmp = path.with_name(f"{plan_id}.{uuid.uuid4().hex}.tmp")
        await run_in_threadpool(tmp.write_bytes, png)
        await run_in_threadpool(os.replace, tmp, path)
        return Response(png, media_type="image/png")
    return Response(await run_in_threadpool(path.read_bytes), media_type="image/png")
