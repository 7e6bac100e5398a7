"""Where a ``POST /v1/plans`` spends its time beside the planner: each step of the route, timed in process.

Run: MUJOCO_GL=egl .venv/bin/python benchmarks/bench_plan_route.py [--n 300] [--hand pisa_iit_softhand]
     [--strategy C]

The app of ``softsig_service.api.app.create_app`` on a fresh data folder (SQLite registry inside) plans the built-in
box at random poses (x in [0.4, 0.6] m, y in [-0.15, 0.15] m, yaw in [-pi, pi]; fixed seed), one plan at a time in
this thread, by the route's own steps in the route's order: the body's validation, the hand's registry row, the
object, the output frame, the capture model lookup, the planner, the plan's JSON (``to_json_dict`` and
``api_json``), the request's dump, the plan's insert, the response model's validation and its JSON. Printed: the
mean wall time per plan of each step [ms] and their sum beside the planner's. No HTTP: the ASGI stack's share is
what ``benchmarks/bench_api.py --per-request`` measures beyond this.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import random
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")


def main() -> None:
    from softsig_service import registry as repo
    from softsig_service.api.app import create_app
    from softsig_service.api.plan_schemas import PlanIn, PlanOut
    from softsig_service.api.routes import plans as route
    from softsig_service.config import Settings
    from softsig_service.objects.frames import output_frame_pose
    from softsig_service.planning.request import PlanRequest
    from softsig_service.services.serialize import api_json

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=300, help="plans")
    parser.add_argument("--hand", default="pisa_iit_softhand")
    parser.add_argument("--strategy", default="C", choices=("S", "C"))
    args = parser.parse_args()

    rng = random.Random(0)
    bodies = [
        json.dumps({
            "hand": args.hand, "strategy": args.strategy,
            "object": {"kind": "builtin", "name": "box", "pose": {
                "x": rng.uniform(0.4, 0.6), "y": rng.uniform(-0.15, 0.15), "yaw": rng.uniform(-math.pi, math.pi)}},
        })
        for _ in range(args.n + 10)
    ]  # fmt: skip
    data_dir = Path(tempfile.mkdtemp(prefix="bench_plan_route_"))
    app = create_app(Settings(data_dir=data_dir, compute_workers=1, warm_planner=False))
    totals: dict[str, float] = {}

    def run(body_text: str, count: bool) -> None:
        ctx = app.state.ctx
        t = time.perf_counter()

        def tick(name: str) -> None:
            nonlocal t
            now = time.perf_counter()
            if count:
                totals[name] = totals.get(name, 0.0) + (now - t)
            t = now

        body = PlanIn.model_validate_json(body_text)
        tick("body validation")
        hand = route._plan_hand(ctx, body)
        tick("hand row")
        obj, obstacles = route.scene_objects(body.object, body.obstacles, body, route.stored_objects(ctx))
        frame = output_frame_pose(body.output_frame, route.scene_frames(body), obj.pose)
        tick("object and frame")
        capture = route.capture_model(ctx, hand, obj, body.capture_version, required=False)
        tick("capture model lookup")
        options = body.model_dump(include=set(route.PLANNER_FIELDS))
        request = PlanRequest(
            hand=hand.manifest_path, obj=obj, capture=capture, hand_revision=hand.token, obstacles=obstacles,
            **options,
        )  # fmt: skip
        tick("planner request")
        plan = ctx.planner.plan(request)
        tick("planner")
        data = api_json(plan.to_json_dict(body.output_frame, frame))
        data["hand_revision"] = hand.revision
        tick("plan JSON")
        stored = body.model_dump(mode="json")
        rec = repo.add_plan(
            ctx.registry, hand=plan.hand, strategy=plan.strategy, success=plan.success, request=stored, result=data
        )
        tick("insert")
        data.update(id=rec.id, created_at=rec.created_at, links=route._links(rec.id))
        answer = PlanOut.model_validate(data)
        tick("response validation")
        PlanOut.__pydantic_serializer__.to_json(answer)
        tick("response JSON")

    async def session() -> None:
        async with app.router.lifespan_context(app):
            for b in bodies[:10]:  # builds the hand's planning model, warms the caches
                run(b, count=False)
            for b in bodies[10:]:
                run(b, count=True)

    asyncio.run(session())
    print(f"{args.n} plans, strategy {args.strategy}, hand {args.hand}: mean wall time per plan [ms]")
    for name, seconds in totals.items():
        print(f"  {name:22s} {seconds / args.n * 1e3:7.3f}")
    rest = sum(v for k, v in totals.items() if k != "planner")
    print(f"  {'all but the planner':22s} {rest / args.n * 1e3:7.3f}")


if __name__ == "__main__":
    main()
