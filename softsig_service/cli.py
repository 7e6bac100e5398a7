"""The ``softsig`` command line (typer): hands, signatures, planning, validation and the service."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()  # headless EGL by default; must run before anything imports MuJoCo

from softsig_service.cli_support import CriterionOption, CsMethodOption, PlacementOption, plan_options  # noqa: E402
from softsig_service.cli_support import emit as _emit  # noqa: E402
from softsig_service.cli_support import errors_to_exit as _errors  # noqa: E402
from softsig_service.cli_support import parse_object as _object_arg  # noqa: E402
from softsig_service.config import Settings  # noqa: E402

app = typer.Typer(
    help="softsig: closure and stiffness signatures of soft hands, and top-grasp planning.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
hands_app = typer.Typer(
    help="The hand library: list, show, close and render hands; add one to a service.", no_args_is_help=True
)
app.add_typer(hands_app, name="hands")
signature_app = typer.Typer(help="Closure and stiffness signatures of a hand.", no_args_is_help=True)
app.add_typer(signature_app, name="signature")


def _write_json(path: Path, data: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data) + "\n", encoding="utf-8")


@hands_app.command("list")
def hands_list(as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False) -> None:
    """List the built-in hands."""
    from softsig_service.hands.model import builtin_hand_names, load_hand

    with _errors():
        settings = Settings()
        rows = []
        for name in builtin_hand_names(settings):
            hand = load_hand(name, settings)
            rows.append(
                {
                    "name": name,
                    "kind": hand.manifest.kind,
                    "joints": int(hand.model.njnt),
                    "actuators": int(hand.model.nu),
                    "reference_points": len(hand.points),
                    "description": hand.manifest.description,
                }
            )

        def text() -> str:
            lines = [f"{'name':20s} {'kind':15s} {'joints':>6s} {'acts':>5s}  description"]
            lines += [
                f"{r['name']:20s} {r['kind']:15s} {r['joints']:6d} {r['actuators']:5d}  {r['description']}"
                for r in rows
            ]
            return "\n".join(lines)

        _emit(rows, as_json, text)


@hands_app.command("show")
def hands_show(
    hand: Annotated[str, typer.Argument(help="built-in name or path to hand.toml")],
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
) -> None:
    """Show one hand: model statistics, reference points, closure and physical parameters."""
    from softsig_service.hands.model import load_hand
    from softsig_service.hands.summary import hand_info

    with _errors():
        info = hand_info(load_hand(hand, Settings()))

        def text() -> str:
            lines = [
                f"{info['name']}: {info['description']}",
                f"  model: {info['model_file']} ({info['model_format']})",
            ]
            lines.append(f"  bodies {info['bodies']}, joints {len(info['joints'])}, actuators {info['actuators']}")
            frame = info["hand_frame"]

            def vec(v: list[float]) -> str:
                return "(" + ", ".join(f"{round(x, 3) + 0.0:+.3f}" for x in v) + ")"

            lines.append(f"  mass {info['mass']:.3f} kg, mount body '{info['mount']}'")
            lines.append(f"  hand frame in '{frame['relative_to']}': origin {vec(frame['origin'])} m")
            lines += [f"    +{a} {vec(frame[a])}" for a in ("x", "y", "z")]
            if info["expanded_urdf"] is not None:
                lines.append(f"  expanded URDF sha256 {info['expanded_urdf']['sha256']}")
            if info["mimics"]:
                lines.append(f"  mimic couplings: {len(info['mimics'])}")
            lines.append("  reference points: " + ", ".join(p["name"] for p in info["reference_points"]))
            lines.append(f"  closure: {info['closure']}")
            return "\n".join(lines)

        _emit(info, as_json, text)


@hands_app.command("close")
def hands_close(
    hand: Annotated[str, typer.Argument(help="built-in name or path to hand.toml")],
    out: Annotated[Path, typer.Option("--out", help="trajectory JSON to write")],
    gravity: Annotated[bool | None, typer.Option("--gravity/--no-gravity", help="override the manifest")] = None,
) -> None:
    """Simulate a free-space closure and write the reference-point trajectories (hand frame, metres)."""
    from softsig_service.hands.closure import simulate_closure
    from softsig_service.hands.model import load_hand
    from softsig_service.hands.summary import closure_summary

    with _errors():
        traj = simulate_closure(load_hand(hand, Settings()), gravity=gravity, surface_points=0)
        _write_json(out, traj.to_json_dict())
        s = closure_summary(traj)
        typer.echo(
            f"{traj.hand}: {s['frames']} frames over {s['duration']:.2f} s, {s['points']} points; fingertip spread "
            f"{s['spread_open'] * 1000:.1f} -> {s['spread_closed'] * 1000:.1f} mm; wrote {out}"
        )


@hands_app.command("render")
def hands_render(
    hand: Annotated[str, typer.Argument(help="built-in name or path to hand.toml")],
    out: Annotated[Path, typer.Option("--out", help="PNG to write")],
    size: Annotated[int, typer.Option(help="width and height of each view [px]", min=64, max=2048)] = 480,
) -> None:
    """Render the hand open and closed side by side (offscreen)."""
    from softsig_service.hands.model import load_hand
    from softsig_service.hands.render import render_open_closed, save_png

    with _errors():
        image = render_open_closed(load_hand(hand, Settings()), width=size, height=size)
        save_png(image, out)
        typer.echo(f"wrote {out} ({image.shape[1]}x{image.shape[0]})")


@hands_app.command("add")
def hands_add(
    path: Annotated[Path, typer.Argument(help="a hand's folder (with hand.toml) or a .zip/.tar.gz of it")],
    url: Annotated[
        str, typer.Option("--url", envvar="SOFTSIG_URL", help="the softsig service (default SOFTSIG_URL)")
    ] = "http://127.0.0.1:8000",
    api_key: Annotated[
        str | None, typer.Option("--api-key", envvar="SOFTSIG_API_KEY", help="X-API-Key (default SOFTSIG_API_KEY)")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
) -> None:
    """Register a hand with a softsig service in one call: a folder is packed as .tar.gz, an archive sent as is.

    The service checks every file (paths, links, sizes), expands a .urdf.xacro in a limited process and loads
    the hand; a problem is printed with its field and the command exits 2.
    """
    import httpx

    from softsig_service.api.client import ApiError, SoftsigClient
    from softsig_service.errors import InvalidInput
    from softsig_service.hands.archive import is_archive, pack_folder

    with _errors():
        limits = Settings().limits
        if path.is_dir():
            upload = (f"{path.resolve().name}.tar.gz", pack_folder(path, limits))
        elif path.is_file() and is_archive(path.name):
            upload = (path.name, path.read_bytes())
        else:
            raise InvalidInput("give a hand's folder or a .zip/.tar.gz archive", field="path", value=str(path))
        try:
            with SoftsigClient(url, api_key=api_key) as api:
                hand = api.register_hand_archive(upload)
        except ApiError as exc:
            problem = exc.problem
            typer.echo(f"error: {exc.status} {problem.detail} | field: {problem.field} | got: {problem.value!r}",
                       err=True)  # fmt: skip
            raise typer.Exit(2) from None
        except httpx.HTTPError as exc:
            typer.echo(f"error: cannot reach the softsig service at {url}: {exc}", err=True)
            raise typer.Exit(2) from None
        data = hand.model_dump(mode="json")
        _emit(data, as_json, lambda: f"registered {hand.name} (revision {hand.revision}, {hand.etag}) at {url}")


@signature_app.command("closure")
def signature_closure(
    hand: Annotated[str | None, typer.Argument(help="built-in name or path to hand.toml (simulated closure)")] = None,
    markers: Annotated[
        Path | None, typer.Option("--markers", help="tracked markers instead: CSV (time,point,x,y,z) or JSON")
    ] = None,
    method: Annotated[str, typer.Option(help="ellipsoid | pca | mesh")] = "ellipsoid",
    criterion: Annotated[
        str,
        typer.Option(
            help="ellipsoid method: absolute (change of the half-width [m], the default) | relative (that change "
            "/ the initial half-width); ignored by pca and mesh"
        ),
    ] = "absolute",
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
    plot: Annotated[Path | None, typer.Option("--plot", help="PNG/PDF/SVG of points, ellipsoids and the CS")] = None,
) -> None:
    """Compute a hand's closure signature (CS) from a simulated closure or from tracked markers.

    Everything is in the hand frame; the ellipsoid criterion is in the JSON's ``params.criterion``.
    """
    from softsig_service.errors import InvalidInput
    from softsig_service.signatures.closure import METHODS, check_criterion, compute_closure_signature

    with _errors():
        if method not in METHODS:
            raise InvalidInput("unknown closure-signature method", field="method", value=method, choices=METHODS)
        the_criterion = check_criterion(criterion)
        if (hand is None) == (markers is None):
            raise InvalidInput("give either a hand or --markers FILE", field="hand")
        if markers is not None:
            from softsig_service.signatures.markers import load_markers

            traj = load_markers(markers)
        else:
            from softsig_service.hands.closure import simulate_closure
            from softsig_service.hands.model import load_hand

            assert hand is not None
            traj = simulate_closure(load_hand(hand, Settings()), surface_points=None if method == "mesh" else 0)
        cs = compute_closure_signature(traj, method, criterion=the_criterion)
        if plot is not None:
            from softsig_service.signatures.plot import plot_closure_signature

            plot_closure_signature(traj, cs, plot)
        data = cs.to_json_dict()

        def text() -> str:
            ax = ", ".join(f"{v:+.3f}" for v in cs.axis)
            how = f"{method}, {cs.params['criterion']} criterion" if "criterion" in cs.params else method
            lines = [
                f"{traj.hand}: closure signature ({how}) in the hand frame",
                f"  axis        ({ax})",
                f"  anchor      ({', '.join(f'{v:.4f}' for v in cs.anchor)}) m",
                f"  magnitude   {cs.magnitude:+.4f}  [{data['extras'].get('magnitude_unit', '')}]",
                f"  deformation {', '.join(f'{v:+.4f}' for v in cs.deformation)}",
                f"  distinctness {cs.distinctness:.3g}" + ("  (ambiguous)" if cs.ambiguous else ""),
            ]
            if plot is not None:
                lines.append(f"  wrote {plot}")
            return "\n".join(lines)

        _emit(data, as_json, text)


@signature_app.command("stiffness")
def signature_stiffness(
    hand: Annotated[str, typer.Argument(help="built-in name or path to hand.toml")],
    obj: Annotated[
        str, typer.Option("--object", help="box | apple | cylinder | sphere:R (radius [m]) | PATH.json")
    ] = "apple",
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
    plot: Annotated[Path | None, typer.Option("--plot", help="PNG of break forces and the stiffness ellipsoid")] = None,
    axes_only: Annotated[
        bool, typer.Option("--axes-only", help="pull along +-x, +-y, +-z only (6 directions)")
    ] = False,
) -> None:
    """Grasp an object in MuJoCo: 6x6 grasp stiffness at the object and break forces per pull direction."""
    from softsig_service.hands.model import load_hand
    from softsig_service.signatures.pullout import AXIS_DIRECTIONS, compute_stiffness_signature

    with _errors():
        the_obj = _stiffness_object(obj)
        ss = compute_stiffness_signature(
            load_hand(hand, Settings()), the_obj, directions=AXIS_DIRECTIONS if axes_only else None
        )
        if plot is not None:
            from softsig_service.signatures.ss_plot import plot_stiffness_signature

            plot_stiffness_signature(ss, plot)
        data = ss.to_json_dict()

        def text() -> str:
            pt, pr = ss.principal_translational, ss.principal_rotational
            held = data["parameters"]["grasp"]["held"]
            lines = [
                f"{hand}: stiffness signature on {data['object'].get('name') or data['object'].get('kind')} "
                f"(hand frame){'' if held else ' - the hand does not hold the object on its own'}",
                "  translational stiffness [N/m]  " + ", ".join(f"{v:.4g}" for v in pt.values),
                "  rotational stiffness [N·m/rad] " + ", ".join(f"{v:.4g}" for v in pr.values),
                "  break forces [N]:",
            ]
            for b in ss.break_forces:
                d = ", ".join(f"{v:+.2f}" for v in b.direction)
                lines.append(f"    ({d})  {b.force:7.2f}  {b.reason}")
            if plot is not None:
                lines.append(f"  wrote {plot}")
            return "\n".join(lines)

        _emit(data, as_json, text)


def _stiffness_object(spec: str) -> Any:
    """``box|apple|cylinder``, ``sphere:R`` (radius [m]) or a JSON file: the object held in the hand."""
    from softsig_service.errors import InvalidInput
    from softsig_service.planning.objects import BUILTIN_NAMES, builtin_object, sphere

    if spec in BUILTIN_NAMES:
        return builtin_object(spec)
    if spec.startswith("sphere:"):
        try:
            radius = float(spec.split(":", 1)[1])
        except ValueError:
            raise InvalidInput("sphere:R needs a radius in metres", field="object", value=spec) from None
        return sphere(radius, mass=0.1)
    return _object_arg(spec, 0.5, 0.0, 0.0)


def _floats(text: str, n: int, field: str) -> tuple[float, ...]:
    from softsig_service.errors import InvalidInput

    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise InvalidInput("expected comma-separated numbers", field=field, value=text) from None
    if len(values) != n:
        raise InvalidInput(f"expected {n} comma-separated numbers", field=field, value=text)
    return values


@app.command("plan")
def plan(
    hand: Annotated[str, typer.Option("--hand", help="built-in name or path to hand.toml")],
    obj: Annotated[str, typer.Option("--object", help="box | apple | cylinder | PATH.json")],
    x: Annotated[float, typer.Option("--x", help="object centre x in base_link [m]")] = 0.5,
    y: Annotated[float, typer.Option("--y", help="object centre y in base_link [m]")] = 0.0,
    yaw: Annotated[float, typer.Option("--yaw", help="object yaw about world z [rad]")] = 0.0,
    strategy: Annotated[str, typer.Option("--strategy", help="S (bounding box) | C (closure signature)")] = "C",
    current_q: Annotated[
        str | None, typer.Option("--current-q", help="current UR5 joints q1,...,q6 [rad] (default: home)")
    ] = None,
    closing_axis: Annotated[str, typer.Option(help="object axis the CS closes across: minor | major")] = "minor",
    cs_method: CsMethodOption = "ellipsoid",
    criterion: CriterionOption = "absolute",
    placement: PlacementOption = "open_centre",
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
) -> None:
    """Plan a UR5 top grasp of an object on the table with strategy S or C."""
    from softsig_service.planning.planner import Planner, PlanRequest

    with _errors():
        q = _floats(current_q, 6, "current_q") if current_q is not None else None
        request = PlanRequest(
            hand=hand, obj=_object_arg(obj, x, y, yaw), strategy=strategy,  # type: ignore[arg-type]
            current_q=q, closing_axis=closing_axis,  # type: ignore[arg-type]
            **plan_options(cs_method, criterion, placement),  # type: ignore[arg-type]
        )  # fmt: skip
        result = Planner().plan(request)
        data = result.to_json_dict()

        def text() -> str:
            lines = [f"{result.hand} / {request.obj.name or request.obj.kind} / strategy {result.strategy}: "
                     + ("success" if result.success else "FAILED: " + ", ".join(result.reasons))]  # fmt: skip
            if result.grasp_pose is not None:
                p = result.grasp_pose[:3, 3]
                lines.append(f"  grasp flange at ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) m in base_link")
            if result.joint_positions is not None:
                lines.append("  joints " + ", ".join(f"{v:+.4f}" for v in result.joint_positions) + " rad")
            qual = result.quality
            if qual["alignment_error"] is not None:
                lines.append(f"  alignment error {qual['alignment_error']:.2e} rad, clearance {qual['clearance']}")
            lines.append(f"  time {result.timing['total'] * 1e3:.1f} ms")
            return "\n".join(lines)

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

        def text() -> str:
            lines = [f"{'hand':20s} {'frames':>6s} {'open [mm]':>10s} {'closed [mm]':>11s} {'ratio':>6s}"]
            lines += [
                f"{r['hand']:20s} {r['frames']:6d} {r['spread_open'] * 1000:10.1f} "
                f"{r['spread_closed'] * 1000:11.1f} {r['spread_ratio']:6.2f}"
                for r in rows
            ]
            return "\n".join(lines)

        _emit(rows, as_json, text)


@app.command("serve")
def serve(
    host: Annotated[str | None, typer.Option(help="address to listen on (default SOFTSIG_HOST or 127.0.0.1)")] = None,
    port: Annotated[int | None, typer.Option(help="port (default SOFTSIG_PORT or 8000)", min=0, max=65535)] = None,
    db: Annotated[
        Path | None, typer.Option("--db", help="SQLite file of the registry (default in SOFTSIG_DATA_DIR)")
    ] = None,
) -> None:
    """Run the REST service (uvicorn): hand and signature registry, plans, validation jobs; docs at /docs."""
    import uvicorn

    from softsig_service.api.app import create_app
    from softsig_service.api.logging import configure_logging

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
        uvicorn.run(
            create_app(settings), host=settings.host, port=settings.port, log_config=None, access_log=False,
            timeout_graceful_shutdown=10,
        )  # fmt: skip


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


def _register_simulation_commands() -> None:
    from softsig_service.simulation.commands import experiment_app, validate

    app.command("validate")(validate)
    app.add_typer(experiment_app, name="experiment")


_register_simulation_commands()


def main() -> None:
    """Entry point for ``python -m softsig_service.cli``."""
    app(prog_name="softsig")


if __name__ == "__main__":
    main()
