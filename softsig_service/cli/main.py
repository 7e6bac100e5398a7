"""The ``softsig`` command line (typer): hands, signatures, planning, validation and the service."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Annotated, Any

import typer

from softsig_service.cli.calibration import calibration_app
from softsig_service.cli.experiments import experiment_app, validate
from softsig_service.cli.hands import hands_app
from softsig_service.cli.options import (
    CaptureOption,
    CriterionOption,
    CsMethodOption,
    HandOption,
    ObjectOption,
    PlacementOption,
    StrategyOption,
    parse_floats,
    read_capture,
    text_table,
)
from softsig_service.cli.options import emit as _emit
from softsig_service.cli.options import errors_to_exit as _errors
from softsig_service.cli.options import parse_object as _object_arg
from softsig_service.cli.signatures import signature_app
from softsig_service.config import Settings
from softsig_service.errors import InvalidInput
from softsig_service.experiments.campaign_spec import plan_option_fields

app = typer.Typer(
    help="softsig: closure and stiffness signatures of soft hands, and top-grasp planning.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
app.add_typer(hands_app, name="hands")
app.add_typer(signature_app, name="signature")
app.command("validate")(validate)
app.add_typer(experiment_app, name="experiment")
app.add_typer(calibration_app, name="calibration")


@app.command("plan")
def plan(
    hand: HandOption,
    obj: ObjectOption,
    x: Annotated[float, typer.Option("--x", help="object centre x in base_link [m]")] = 0.5,
    y: Annotated[float, typer.Option("--y", help="object centre y in base_link [m]")] = 0.0,
    yaw: Annotated[float, typer.Option("--yaw", help="object yaw about world z [rad]")] = 0.0,
    mass: Annotated[float | None, typer.Option("--mass", help="mass of an object file's object [kg]")] = None,
    scale: Annotated[float, typer.Option("--scale", help="scale of an object file's coordinates")] = 1.0,
    strategy: StrategyOption = "C",
    current_q: Annotated[
        str | None, typer.Option("--current-q", help="current UR5 joints q1,...,q6 [rad] (default: home)")
    ] = None,
    closing_axis: Annotated[str, typer.Option(help="object axis the CS closes across: minor | major")] = "minor",
    cs_method: CsMethodOption = "ellipsoid",
    criterion: CriterionOption = "absolute",
    placement: PlacementOption = "open_centre",
    sigma_r: Annotated[float, typer.Option("--sigma-r", help="std. dev. of the object's yaw [rad] (R)")] = 0.0,
    sigma_t: Annotated[float, typer.Option("--sigma-t", help="std. dev. of its x and y [m] (R)")] = 0.0,
    capture: CaptureOption = None,
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
    image: Annotated[
        Path | None, typer.Option("--image", help="write the plan's top view (PNG), as GET /v1/plans/{id}/image.png")
    ] = None,
    candidates: Annotated[
        int, typer.Option("--candidates", min=1, max=12, help="distinct checked grasps to return, best first")
    ] = 1,
    approach_cone: Annotated[
        float, typer.Option("--approach-cone", min=0.0, max=1.0472, help="[rad] C's largest tilt from straight down")
    ] = 0.5235987755982988,
    output_frame: Annotated[
        str,
        typer.Option("--output-frame", help="frame of the answer's poses: base_link | base (UR controller) | object"),
    ] = "base_link",
) -> None:
    """Plan a UR5 top grasp of an object on the table with strategy S, C or R."""
    from softsig_service.planning.planner import Planner
    from softsig_service.planning.request import PlanRequest

    with _errors():
        q = parse_floats(current_q, 6, "current_q") if current_q is not None else None
        target = _object_arg(obj, x, y, yaw, mass=mass, scale=scale)
        model = read_capture(capture, hand=hand, obj=target, strategy=strategy)
        request = PlanRequest(
            hand=hand, obj=target, strategy=strategy,  # type: ignore[arg-type]
            current_q=q, closing_axis=closing_axis,  # type: ignore[arg-type]
            sigma_r=sigma_r, sigma_t=sigma_t, capture=model, candidates=candidates, approach_cone=approach_cone,
            **plan_option_fields(cs_method, criterion, placement),  # type: ignore[arg-type]
        )  # fmt: skip
        from softsig_service.objects.frames import output_frame_pose

        frame = output_frame_pose(output_frame, None, target.pose)
        result = Planner().plan(request)
        data = result.to_json_dict(output_frame, frame)
        if image is not None:
            from softsig_service.hands.model import resolve_hand_path
            from softsig_service.services.plan_image import render_plan_png

            image.parent.mkdir(parents=True, exist_ok=True)
            image.write_bytes(render_plan_png(data, str(resolve_hand_path(hand)), Settings()))

        def text() -> list[str]:
            lines = [f"{result.hand} / {request.obj.name or request.obj.kind} / strategy {result.strategy}: "
                     + ("success" if result.success else "FAILED: " + ", ".join(result.reasons))]  # fmt: skip
            if data["grasp_pose"] is not None:
                p = data["grasp_pose"]["position"]
                lines.append(f"  grasp flange at ({p['x']:.4f}, {p['y']:.4f}, {p['z']:.4f}) m in {output_frame}")
            if result.joint_positions is not None:
                lines.append("  joints " + ", ".join(f"{v:+.4f}" for v in result.joint_positions) + " rad")
            qual = result.quality
            if qual["alignment_error"] is not None:
                lines.append(f"  alignment error {qual['alignment_error']:.2e} rad, clearance {qual['clearance']}")
            if qual.get("expected_capture") is not None:
                lines.append(f"  expected capture under the stated noise {qual['expected_capture']:.3f}")
            for g in data["grasps"][1:]:
                p = g["grasp_pose"]["position"]
                lines.append(f"  grasp {g['rank']}: quality {g['grasp_quality']:.3f} ({g['quality_model']}), flange "
                             f"({p['x']:.4f}, {p['y']:.4f}, {p['z']:.4f}) m, {g['label']}")  # fmt: skip
            lines.append(f"  time {result.timing['total'] * 1e3:.1f} ms")
            return lines

        _emit(data, as_json, text)
        if not result.success:
            raise typer.Exit(1)


@app.command("summary")
def summary(as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False) -> None:
    """Close every built-in hand and print what the closure does to its fingertips."""
    from softsig_service.hands.closure import simulate_closure
    from softsig_service.hands.model import builtin_hand_names, load_hand
    from softsig_service.hands.summary import closure_summary

    with _errors():
        settings = Settings()
        rows = [
            closure_summary(simulate_closure(load_hand(n, settings), surface_points=0))
            for n in builtin_hand_names(settings)
        ]

        mm = [{**r, "open": r["spread_open"] * 1000, "closed": r["spread_closed"] * 1000} for r in rows]
        columns = [("hand", "hand", "20s"), ("frames", "frames", "6d"), ("open [mm]", "open", "10.1f"),
                   ("closed [mm]", "closed", "11.1f"), ("ratio", "spread_ratio", "6.2f")]  # fmt: skip
        _emit(rows, as_json, lambda: text_table(mm, columns))


@app.command("serve")
def serve(
    host: Annotated[str | None, typer.Option(help="address to listen on (default SOFTSIG_HOST or 127.0.0.1)")] = None,
    port: Annotated[int | None, typer.Option(help="port (default SOFTSIG_PORT or 8000)", min=0, max=65535)] = None,
    db: Annotated[
        Path | None, typer.Option("--db", help="SQLite file of the registry (default in SOFTSIG_DATA_DIR)")
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(
            "--workers",
            min=1,
            max=64,
            help="service processes sharing the port and the registry (default SOFTSIG_WORKERS, else every CPU this "
            "process may use)",
        ),
    ] = None,
) -> None:
    """Run the REST service (uvicorn): hand and signature registry, plans, validation jobs; docs at /docs.

    With several workers, each process serves requests and claims jobs from the shared registry; a process that
    dies leaves its jobs to the others once their lease expires (``SOFTSIG_JOB_LEASE``)."""
    import os
    import shutil
    import tempfile

    import uvicorn

    from softsig_service.api.app import create_app
    from softsig_service.api.logging import configure_logging
    from softsig_service.api.serving import ServiceConfig
    from softsig_service.experiments.campaign import default_workers

    with _errors():
        overrides: dict[str, Any] = {}
        if host is not None:
            overrides["host"] = host
        if port is not None:
            overrides["port"] = port
        if db is not None:
            overrides["database_url"] = f"sqlite:///{db.expanduser().resolve()}"
        settings = Settings(**overrides)
        configure_logging(settings.log_level)
        n = workers or settings.workers or default_workers()
        _check_port(settings.host, settings.port)
        common: dict[str, Any] = {
            "host": settings.host, "port": settings.port, "log_config": None, "access_log": False,
            "timeout_graceful_shutdown": 10, "header_timeout": settings.header_timeout,
        }  # fmt: skip
        if n == 1:
            server = uvicorn.Server(ServiceConfig(create_app(settings), **common))
            with contextlib.suppress(KeyboardInterrupt):
                server.run()
            if not server.started:
                raise typer.Exit(3)  # uvicorn's startup failure (it logged why)
            return
        # the worker processes build their settings from the environment: pass the options on that way
        for key, value in overrides.items():
            os.environ[f"SOFTSIG_{key.upper()}"] = str(value)
        # their metrics count together in one folder (prometheus_client's multiprocess mode): a fresh one per run
        # unless PROMETHEUS_MULTIPROC_DIR names one already
        metrics_dir = None
        if not os.environ.get("PROMETHEUS_MULTIPROC_DIR"):
            metrics_dir = tempfile.mkdtemp(prefix="softsig-metrics-")
            os.environ["PROMETHEUS_MULTIPROC_DIR"] = metrics_dir
        # each process migrates the registry and registers the built-in hands at its start; both are safe when
        # processes start together (one upgrade under a lock, one registration per hand)
        try:
            _serve_processes(ServiceConfig("softsig_service.api.app:service_app", factory=True, workers=n, **common))
        finally:
            if metrics_dir is not None:
                shutil.rmtree(metrics_dir, ignore_errors=True)


def _check_port(host: str, port: int) -> None:
    """Refuse, naming ``port``, an address another process listens on (binding it as uvicorn does, then letting go)."""
    import errno
    import socket

    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise InvalidInput(
                    f"port {port} on {host} is already in use (another service, or softsig already running: "
                    f"`ss -ltnp 'sport = :{port}'` shows which); choose another with --port or SOFTSIG_PORT",
                    field="port", value=port,
                ) from None  # fmt: skip
            raise InvalidInput(f"cannot listen on {host}:{port}: {exc.strerror}", field="host", value=host) from None


def _serve_processes(config: Any) -> None:
    """uvicorn's multi-process supervisor on a listening socket with ``TCP_NODELAY``.

    uvicorn binds that socket without naming the protocol, so asyncio does not switch Nagle's algorithm off on the
    connections it accepts, and a response written in two parts (head, body) waits for the client's delayed ACK
    (about 40 ms per request on Linux). Linux copies ``TCP_NODELAY`` from the listening socket to every accepted
    connection."""
    import inspect
    import socket

    import uvicorn
    from uvicorn.supervisors import Multiprocess

    sock = config.bind_socket()
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    extra = {"target": uvicorn.Server(config).run} if "target" in inspect.signature(Multiprocess).parameters else {}
    Multiprocess(config, sockets=[sock], **extra).run()


@app.command("openapi")
def openapi(
    out: Annotated[Path, typer.Option("--out", help="file to write")] = Path("openapi/openapi.json"),
    check: Annotated[bool, typer.Option("--check", help="exit 1 if the file differs from the app's schema")] = False,
) -> None:
    """Export the service's OpenAPI document (sorted keys, indent 2), or check the committed one."""
    from softsig_service.api.app import openapi_json

    text = openapi_json()
    if check:
        current = out.read_text(encoding="utf-8") if out.is_file() else None
        if current != text:
            typer.echo(f"{out} is out of date: run `softsig openapi --out {out}`", err=True)
            raise typer.Exit(1)
        typer.echo(f"{out} is up to date")
        return
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text, encoding="utf-8")
    typer.echo(f"wrote {out}")


def main() -> None:
    """Entry point for ``python -m softsig_service.cli``."""
    app(prog_name="softsig")


if __name__ == "__main__":
    main()
