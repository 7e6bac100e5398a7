"""``softsig signature``: the closure and stiffness signatures of a hand."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from softsig_service.cli.options import CriterionOption, CsMethodOption, HandArgument, PlacementOption
from softsig_service.cli.options import emit as _emit
from softsig_service.cli.options import errors_to_exit as _errors
from softsig_service.cli.options import parse_object as _object_arg
from softsig_service.config import Settings
from softsig_service.experiments.campaign_spec import plan_option_fields

signature_app = typer.Typer(help="Closure and stiffness signatures of a hand.", no_args_is_help=True)


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
    plot: Annotated[
        Path | None,
        typer.Option("--plot", help="PNG/PDF/SVG: points, ellipsoids and the CS in 3-D and top, front, side views"),
    ] = None,
) -> None:
    """Compute a hand's closure signature (CS) from a simulated closure or from tracked markers.

    Everything is in the hand's grasp frame (its hand frame when the manifest gives no ``grasp_frame``; markers in
    the hand frame); the ellipsoid criterion is in the JSON's ``params.criterion``.
    """
    from softsig_service.errors import InvalidInput
    from softsig_service.signatures.closure import check_criterion, compute_closure_signature
    from softsig_service.signatures.closure_types import METHODS

    with _errors():
        if method not in METHODS:
            raise InvalidInput("unknown closure-signature method", field="method", value=method, choices=METHODS)
        the_criterion = check_criterion(criterion)
        if (hand is None) == (markers is None):
            raise InvalidInput("give either a hand or --markers FILE", field="hand")
        frame = "hand frame"
        if markers is not None:
            from softsig_service.signatures.markers import load_markers

            traj = load_markers(markers)
        else:
            from softsig_service.hands.closure import in_grasp_frame, simulate_closure
            from softsig_service.hands.model import load_hand

            assert hand is not None
            the_hand = load_hand(hand, Settings())
            traj = in_grasp_frame(the_hand, simulate_closure(the_hand, surface_points=None if method == "mesh" else 0))
            if the_hand.manifest.grasp_frame is not None:
                frame = "grasp frame"
        cs = compute_closure_signature(traj, method, criterion=the_criterion)
        if plot is not None:
            from softsig_service.experiments.closure_plot import plot_closure_signature

            plot_closure_signature(traj, cs, plot)
        data = cs.to_json_dict()

        def text() -> list[str]:
            ax = ", ".join(f"{v:+.3f}" for v in cs.axis)
            how = f"{method}, {cs.params['criterion']} criterion" if "criterion" in cs.params else method
            lines = [
                f"{traj.hand}: closure signature ({how}) in the {frame}",
                f"  axis        ({ax})",
                f"  anchor      ({', '.join(f'{v:.4f}' for v in cs.anchor)}) m",
                f"  magnitude   {cs.magnitude:+.4f}  [{data['extras'].get('magnitude_unit', '')}]",
                f"  deformation {', '.join(f'{v:+.4f}' for v in cs.deformation)}",
                f"  distinctness {cs.distinctness:.3g}" + ("  (ambiguous)" if cs.ambiguous else ""),
            ]
            if plot is not None:
                lines.append(f"  wrote {plot}")
            return lines

        _emit(data, as_json, text)


@signature_app.command("stiffness")
def signature_stiffness(
    hand: HandArgument,
    obj: Annotated[
        str, typer.Option("--object", help="a built-in name (box, apple, mug, ...) | sphere:R (radius [m]) | PATH.json")
    ] = "apple",
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
    plot: Annotated[Path | None, typer.Option("--plot", help="PNG of break forces and the stiffness ellipsoid")] = None,
    axes_only: Annotated[
        bool, typer.Option("--axes-only", help="pull along +-x, +-y, +-z only (6 directions)")
    ] = False,
) -> None:
    """Grasp an object in MuJoCo: 6x6 grasp stiffness at the object and break forces per pull direction."""
    from softsig_service.hands.model import load_hand
    from softsig_service.simulation.pullout import AXIS_DIRECTIONS
    from softsig_service.simulation.stiffness_signature import compute_stiffness_signature

    with _errors():
        the_obj = _stiffness_object(obj)
        ss = compute_stiffness_signature(
            load_hand(hand, Settings()), the_obj, directions=AXIS_DIRECTIONS if axes_only else None
        )
        if plot is not None:
            from softsig_service.experiments.stiffness_plot import plot_stiffness_signature

            plot_stiffness_signature(ss, plot)
        data = ss.to_json_dict()

        def text() -> list[str]:
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
            return lines

        _emit(data, as_json, text)


def _stiffness_object(spec: str) -> Any:
    """A built-in object's name (Table I's or a household mesh), ``sphere:R`` (radius [m]) or a JSON file: the
    object held in the hand."""
    from softsig_service.errors import InvalidInput
    from softsig_service.objects import OBJECT_NAMES, builtin_object, sphere

    if spec in OBJECT_NAMES:
        return builtin_object(spec)
    if spec.startswith("sphere:"):
        try:
            radius = float(spec.split(":", 1)[1])
        except ValueError:
            raise InvalidInput("sphere:R needs a radius in metres", field="object", value=spec) from None
        return sphere(radius, mass=0.1)
    return _object_arg(spec, 0.5, 0.0, 0.0)


@signature_app.command("capture")
def signature_capture(
    hand: HandArgument,
    out: Annotated[Path, typer.Option("--out", help="JSON file to write the capture model into")],
    obj: Annotated[str, typer.Option("--object", help="box | apple | cylinder | PATH.json")] = "box",
    n_theta: Annotated[int, typer.Option("--n-theta", help="relative yaws over a half turn", min=2, max=72)] = 12,
    half_width: Annotated[float, typer.Option("--half-width", help="largest offset [m]")] = 0.03,
    step: Annotated[float, typer.Option("--step", help="offset step [m]")] = 0.01,
    holdout: Annotated[int, typer.Option("--holdout", help="held-out simulations", min=0)] = 60,
    workers: Annotated[int, typer.Option("--workers", help="worker processes", min=1)] = 1,
    cs_method: CsMethodOption = "ellipsoid",
    criterion: CriterionOption = "absolute",
    placement: PlacementOption = "open_centre",
    as_json: Annotated[bool, typer.Option("--json", help="print the model's summary as JSON")] = False,
) -> None:
    """The capture model of strategy R: grasp simulations of the object over relative poses of the hand (placed
    by the planner with these closure-signature and placement options)."""
    import json

    from softsig_service.experiments.capture import CaptureGrid, build_capture_model

    with _errors():
        grid = CaptureGrid(n_theta=n_theta, half_width=half_width, step=step, holdout=holdout)
        the_obj = _object_arg(obj, 0.5, 0.0, 0.0)
        options = plan_option_fields(cs_method, criterion, placement)
        model = build_capture_model(hand, the_obj.to_json(), grid, workers=workers, plan_options=dict(options))
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(model.to_json_dict()) + "\n", encoding="utf-8")
        summary = {k: model.meta[k] for k in ("simulations", "seconds", "carried_fraction", "holdout_agreement")}

        def text() -> str:
            return (
                f"{hand} on {the_obj.name or the_obj.kind}: {summary['simulations']} simulations in "
                f"{summary['seconds']:.0f} s; carried in {summary['carried_fraction']:.0%} of the grid; the model "
                f"predicts {summary['holdout_agreement']:.0%} of the held-out outcomes; wrote {out}"
            )

        _emit({**summary, "file": str(out)}, as_json, text)
