"""``softsig calibration``: real outcomes in, a calibrated variant of a hand out (docs/calibration.md).

* ``softsig calibration paper-outcomes --out FILE``: the paper's Table I (real robot) in the upload form.
* ``softsig calibration run HAND --outcomes FILE --hold-out SELECTOR ... --out DIR``: fit the hand's declared
  parameters to the outcomes not held out, score the held-out ones, write the variant, report and figure.
"""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from softsig_service.cli.options import errors_to_exit as _errors
from softsig_service.errors import InvalidInput

calibration_app = typer.Typer(
    help="Calibrate a simulated hand to real grasp outcomes, checked on held-out ones.", no_args_is_help=True
)


def paper_outcomes() -> dict[str, Any]:
    """The paper's Table I (real SoftHand on a UR5) as outcome cells: every object x S, C x the three conditions,
    20 trials each (:data:`~softsig_service.experiments.campaign_spec.PAPER_TABLE1`)."""
    from softsig_service.experiments.campaign_spec import PAPER_TABLE1, PAPER_TRIALS, TABLE1_CONDITIONS

    cells = []
    for obj, per_condition in PAPER_TABLE1.items():
        for (sigma_r, sigma_t), counts in zip(TABLE1_CONDITIONS, per_condition, strict=True):
            for strategy, k in zip(("S", "C"), counts, strict=True):
                cells.append(
                    {
                        "object": obj,
                        "strategy": strategy,
                        "sigma_r": sigma_r,
                        "sigma_t": sigma_t,
                        "trials": PAPER_TRIALS,
                        "successes": k,
                    }
                )
    return {"cells": cells, "note": "the paper's Table I: the SoftHand on a UR5, 20 trials per cell"}


def parse_selector(text: str) -> dict[str, Any]:
    """``object=box,strategy=S,sigma_r=0.2,sigma_t=0.02`` (any of them) as a selector mapping."""
    out: dict[str, Any] = {}
    for part in (p.strip() for p in text.split(",") if p.strip()):
        key, sep, value = part.partition("=")
        if not sep or key not in ("object", "strategy", "sigma_r", "sigma_t"):
            raise InvalidInput(
                "a selector is key=value pairs of object, strategy, sigma_r, sigma_t",
                field="hold_out",
                value=text,
            )
        try:
            out[key] = float(value) if key.startswith("sigma") else value
        except ValueError:
            raise InvalidInput("sigma_r and sigma_t are numbers", field="hold_out", value=text) from None
    return out


def parse_range(text: str) -> tuple[str, tuple[float, float]]:
    """``name=low:high`` as (name, (low, high))."""
    name, sep, span = text.partition("=")
    low, sep2, high = span.partition(":")
    try:
        if not sep or not sep2:
            raise ValueError
        return name.strip(), (float(low), float(high))
    except ValueError:
        raise InvalidInput("a range is name=low:high", field="range", value=text) from None


@calibration_app.command("paper-outcomes")
def paper_outcomes_command(
    out: Annotated[Path, typer.Option("--out", help="JSON file to write")],
) -> None:
    """Write the paper's real Table I as an outcomes file (the form ``calibration run`` and the API take)."""
    out.write_text(json.dumps(paper_outcomes(), indent=1) + "\n", encoding="utf-8")
    typer.echo(f"wrote {out}")


@calibration_app.command("run")
def run(
    hand: Annotated[str, typer.Argument(help="built-in name or path to hand.toml")],
    outcomes: Annotated[Path, typer.Option("--outcomes", help="JSON: {cells: [...]} and/or {trials: [...]}")],
    out: Annotated[Path, typer.Option("--out", help="output folder")],
    hold_out: Annotated[
        list[str] | None,
        typer.Option("--hold-out", help="cells held out of the fit, e.g. sigma_r=0.2,sigma_t=0.02 (repeatable)"),
    ] = None,
    parameter: Annotated[
        list[str] | None, typer.Option("--parameter", help="declared parameter to fit (repeatable; default all)")
    ] = None,
    ranges: Annotated[
        list[str] | None, typer.Option("--range", help="a narrower range, name=low:high (repeatable)")
    ] = None,
    budget: Annotated[int, typer.Option("--budget", help="simulations for the fit", min=1)] = 2000,
    trials_per_cell: Annotated[
        int, typer.Option("--trials-per-cell", help="draws per noisy fitted cell per parameter set", min=1)
    ] = 20,
    test_trials: Annotated[int, typer.Option("--test-trials", help="draws per noisy held-out cell", min=1)] = 40,
    seed: Annotated[int, typer.Option("--seed", min=0)] = 0,
    name: Annotated[str, typer.Option("--name", help="the calibrated variant's name")] = "",
    workers: Annotated[int, typer.Option("--workers", help="simulation processes", min=1)] = 2,
    as_json: Annotated[bool, typer.Option("--json", help="print the result as JSON")] = False,
) -> None:
    """Fit the hand's declared calibration parameters to real outcomes (beta-binomial likelihood, Optuna TPE,
    common random numbers), predict the held-out cells with the calibrated and the uncalibrated model, and write
    ``variant/<name>/hand.toml``, ``calibration.json``, ``evaluations.jsonl``, ``report.md``, ``calibration.png``."""
    with _errors():
        from softsig_service.experiments.calibration import CalibrationSpec, calibrate
        from softsig_service.experiments.calibration_report import write_calibration_report
        from softsig_service.experiments.outcomes import CellSelector, outcomes_from_json, parse_model

        try:
            data = json.loads(outcomes.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InvalidInput(f"cannot read the outcomes: {exc}", field="outcomes", value=str(outcomes)) from None
        selectors = tuple(
            parse_model(CellSelector, parse_selector(s), prefix=f"hold_out[{k}]") for k, s in enumerate(hold_out or [])
        )
        spec = CalibrationSpec(
            hand=hand,
            outcomes=outcomes_from_json(data),
            held_out=selectors,
            parameters=tuple(parameter or ()),
            ranges=dict(parse_range(r) for r in ranges or ()),
            budget=budget,
            trials_per_cell=trials_per_cell,
            test_trials=test_trials,
            seed=seed,
            name=name,
        )

        def progress(done: int, planned: int, message: str) -> None:
            typer.echo(f"[{done}/{planned} simulations] {message}", err=True)

        result = calibrate(spec, out, workers=workers, progress=progress)
        payload = result.to_json_dict()
        command = "softsig calibration " + " ".join(shlex.quote(a) for a in sys.argv[2:])
        files = write_calibration_report(payload, out, command)
        if as_json:
            typer.echo(json.dumps(payload, indent=1))
            return
        held = payload["heldout_loglik"]
        typer.echo(f"calibrated {payload['calibrated']} (defaults {payload['defaults']})")
        if held:
            typer.echo(
                "held-out log-likelihood: calibrated {calibrated:.2f}, uncalibrated {uncalibrated:.2f}, "
                "constant rate {constant_rate:.2f}".format(**held)
            )
        typer.echo(f"variant {result.variant}; report {files['report']}; figure {files['figure']}")
