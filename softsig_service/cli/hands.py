"""``softsig hands``: list, show, close and render the hands of the library, and add one to a service."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from softsig_service.cli.options import HandArgument, text_table, write_json
from softsig_service.cli.options import emit as _emit
from softsig_service.cli.options import errors_to_exit as _errors
from softsig_service.config import Settings

hands_app = typer.Typer(
    help="The hand library: list, show, close and render hands; add one to a service.", no_args_is_help=True
)


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

        columns = [("name", "name", "20s"), ("kind", "kind", "15s"), ("joints", "joints", "6d"),
                   ("acts", "actuators", "5d"), ("description", "description", "s")]  # fmt: skip
        _emit(rows, as_json, lambda: text_table(rows, columns))


def _hand_lines(info: dict[str, Any]) -> list[str]:
    """The text of ``softsig hands show``: a hand's summary (``hand_info``) as lines."""
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
    if info["excluded_pairs"]:
        lines.append(f"  self-collision pairs not checked: {len(info['excluded_pairs'])}")
        lines += [f"    {p['body1']} / {p['body2']}: {p['reason']} ({p['detail']})" for p in info["excluded_pairs"]]
    lines.append("  reference points: " + ", ".join(p["name"] for p in info["reference_points"]))
    lines.append(f"  closure: {info['closure']}")
    return lines


@hands_app.command("show")
def hands_show(
    hand: HandArgument,
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
) -> None:
    """Show one hand: model statistics, reference points, closure and physical parameters."""
    from softsig_service.hands.model import load_hand
    from softsig_service.hands.summary import hand_info

    with _errors():
        info = hand_info(load_hand(hand, Settings()))

        _emit(info, as_json, lambda: _hand_lines(info))


@hands_app.command("close")
def hands_close(
    hand: HandArgument,
    out: Annotated[Path, typer.Option("--out", help="trajectory JSON to write")],
    gravity: Annotated[bool | None, typer.Option("--gravity/--no-gravity", help="override the manifest")] = None,
) -> None:
    """Simulate a free-space closure and write the reference-point trajectories (hand frame, metres)."""
    from softsig_service.hands.closure import simulate_closure
    from softsig_service.hands.model import load_hand
    from softsig_service.hands.summary import closure_summary

    with _errors():
        traj = simulate_closure(load_hand(hand, Settings()), gravity=gravity, surface_points=0)
        write_json(out, traj.to_json_dict())
        s = closure_summary(traj)
        typer.echo(
            f"{traj.hand}: {s['frames']} frames over {s['duration']:.2f} s, {s['points']} points; fingertip spread "
            f"{s['spread_open'] * 1000:.1f} -> {s['spread_closed'] * 1000:.1f} mm; wrote {out}"
        )


@hands_app.command("render")
def hands_render(
    hand: HandArgument,
    out: Annotated[Path, typer.Option("--out", help="PNG to write")],
    size: Annotated[int, typer.Option(help="width and height of each view [px]", min=64, max=2048)] = 480,
    cs_method: Annotated[
        str, typer.Option("--cs-method", help="closure signature drawn: ellipsoid | pca | mesh | none")
    ] = "ellipsoid",
) -> None:
    """Render the hand open and closed side by side (offscreen, white background): the hand frame's axes, the
    grasp frame when the manifest gives one, and the closure signature's axis (ellipsoid, absolute criterion, as
    ``softsig signature closure`` computes it; ``--cs-method none`` leaves it out)."""
    from softsig_service.errors import InvalidInput
    from softsig_service.hands.model import load_hand
    from softsig_service.hands.render import render_open_closed, save_png
    from softsig_service.signatures.closure_types import METHODS
    from softsig_service.simulation.hand_signature import hand_closure_signature

    with _errors():
        if cs_method != "none" and cs_method not in METHODS:
            raise InvalidInput(
                "unknown closure-signature method", field="cs_method", value=cs_method, choices=(*METHODS, "none")
            )
        the_hand = load_hand(hand, Settings())
        signature = None if cs_method == "none" else hand_closure_signature(the_hand, cs_method)  # type: ignore[arg-type]
        image = render_open_closed(the_hand, width=size, height=size, signature=signature)
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
