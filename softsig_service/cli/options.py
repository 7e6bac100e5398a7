"""Helpers shared by the command-line modules: error reporting, output and the object argument."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer

from softsig_service.errors import InvalidInput, SoftsigError


@contextmanager
def errors_to_exit() -> Iterator[None]:
    """Print a :class:`SoftsigError` as one clear line on stderr and exit with status 2."""
    try:
        yield
    except SoftsigError as exc:
        typer.echo(f"error: {exc.describe()}", err=True)
        raise typer.Exit(2) from None


def emit(data: Any, as_json: bool, text: Callable[[], str | list[str]]) -> None:
    """Print ``data`` as indented JSON with ``as_json`` (in the REST API's form: vectors as ``{"x", "y", "z"}``, no
    NaN, no negative zero), else what ``text()`` gives (a string or lines)."""
    if as_json:
        from softsig_service.services.serialize import api_json

        typer.echo(json.dumps(api_json(data), indent=2))
    else:
        out = text()
        typer.echo(out if isinstance(out, str) else "\n".join(out))


def text_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[tuple[str, str, str]]) -> list[str]:
    """``rows`` as lines of aligned columns, a heading line first. Each column is ``(heading, key, spec)``: the
    row's value under ``key`` formatted with the format ``spec`` ("20s", "6d", "10.1f", ...); a heading is aligned
    as its values (left for text, right for numbers) and as wide as the spec's width, or unbounded without one."""

    def heading(title: str, spec: str) -> str:
        width = spec[: len(spec) - len(spec.lstrip("0123456789"))]
        return format(title, ("<" if spec.endswith("s") else ">") + width)

    lines = [" ".join(heading(title, spec) for title, _, spec in columns).rstrip()]
    lines += [" ".join(format(row[key], spec) for _, key, spec in columns).rstrip() for row in rows]
    return lines


def parse_object(spec: str, x: float, y: float, yaw: float, *, mass: float | None = None, scale: float = 1.0) -> Any:
    """A built-in object's name (``box|apple|cylinder``, or a shipped household mesh: ``mug|banana|power_drill|
    mustard_bottle``), a path to an object JSON, or a mesh or cloud file (``.stl``, ``.obj``, ``.ply``,
    ``.pcd``; :mod:`softsig_service.objects.files`; ``mass`` [kg] required, ``scale`` on its coordinates). A
    primitive or mesh is placed at (x, y, yaw) on the table; a cloud's points are taken in ``base_link`` as they
    are."""
    from softsig_service.objects import OBJECT_NAMES, builtin_object, object_from_json
    from softsig_service.objects.files import SUFFIXES, object_from_file

    if spec in OBJECT_NAMES:
        return builtin_object(spec, x=x, y=y, yaw=yaw)
    path = Path(spec)
    if path.suffix.lower() not in (".json", *SUFFIXES) or not path.is_file():
        choices = [*OBJECT_NAMES, "PATH.json", *(f"PATH{s}" for s in SUFFIXES)]
        raise InvalidInput("object must be a built-in name, an object JSON or a mesh or cloud file", field="object",
                           value=spec, choices=choices)  # fmt: skip
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InvalidInput(f"object file is not valid JSON: {exc}", field="object", value=spec) from None
    else:
        if mass is None:
            raise InvalidInput("a mesh or cloud file needs the object's mass (--mass, kg)", field="mass")
        data = object_from_file(path.read_bytes(), path.name, mass=mass, scale=scale, field="object")
    if isinstance(data, dict) and data.get("kind") != "points":
        data = {**data, "pose": {**data.get("pose", {}), "x": x, "y": y, "yaw": yaw}}
    return object_from_json(data)


CsMethodOption = Annotated[str, typer.Option("--cs-method", help="closure signature for C: ellipsoid | pca | mesh")]
CriterionOption = Annotated[
    str, typer.Option("--criterion", help="ellipsoid CS criterion: absolute [m] (docs/design.md §4) | relative")
]
PlacementOption = Annotated[
    str,
    typer.Option(
        "--placement",
        help="hand point over the object's centre, the same for S and C: open_centre | grasp_centre | knuckle "
        "(the manifest's knuckle point); or per_strategy (previous: its deprecated name)",
    ),
]


StrategyOption = Annotated[
    str, typer.Option("--strategy", help="S (bounding box) | C (closure signature) | R (robust; needs --capture)")
]
HandOption = Annotated[str, typer.Option("--hand", help="built-in name or path to hand.toml")]
HandArgument = Annotated[str, typer.Argument(help="built-in name or path to hand.toml")]
ObjectOption = Annotated[
    str,
    typer.Option(
        "--object",
        help="box | apple | cylinder | mug | banana | power_drill | mustard_bottle | PATH.json | "
        "PATH.stl|.obj|.ply|.pcd (with --mass)",
    ),
]
CaptureOption = Annotated[
    Path | None,
    typer.Option(
        "--capture",
        help="capture model JSON (softsig signature capture) for strategy R (default for a built-in hand and "
        "object: the model shipped in hands/<name>/capture/)",
    ),
]


def read_capture(path: Path | None, *, hand: str = "", obj: Any = None, strategy: str = "") -> Any:
    """The :class:`~softsig_service.signatures.capture.CaptureModel` in ``path``; without a path, the model shipped
    with the hand for an object of the shape of ``obj`` (strategy R plans with it; every strategy's grasp_quality
    comes from it) (a ``TableObject``; the lookup the
    service makes too, :func:`~softsig_service.experiments.capture.shipped_capture_for`), else None.
    :class:`InvalidInput` naming ``capture`` when it cannot be read."""
    if path is None and obj is not None:
        from softsig_service.experiments.capture import shipped_capture_for
        from softsig_service.hands.model import builtin_hand_names, builtin_hands_dir

        folder = builtin_hands_dir() / hand if hand in builtin_hand_names() else Path(hand).parent
        path = shipped_capture_for(folder, obj)
    if path is None:
        return None
    from softsig_service.signatures.capture import CaptureModel

    try:
        return CaptureModel.from_json_dict(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError) as exc:
        raise InvalidInput(f"cannot read the capture model: {exc}", field="capture", value=str(path)) from None


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as one line of JSON to ``path`` (parent folders made)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data) + "\n", encoding="utf-8")


def parse_floats(text: str, n: int, field: str) -> tuple[float, ...]:
    """``n`` comma-separated numbers from ``text``; :class:`InvalidInput` naming ``field`` otherwise."""

    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise InvalidInput("expected comma-separated numbers", field=field, value=text) from None
    if len(values) != n:
        raise InvalidInput(f"expected {n} comma-separated numbers", field=field, value=text)
    return values
