"""The computations the API and the CLI share, as plain functions importable by a spawned worker process:
checking a hand, closure signatures from a simulated closure or from markers, and the job callables
(``fn(params, ctx) -> dict``, see :mod:`softsig_service.services.jobs`) of stiffness signatures, validations and the
reference experiment.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from softsig_service.config import ModelLimits, Settings
from softsig_service.errors import InvalidHandModel, SoftsigError
from softsig_service.experiments.progress import Progress
from softsig_service.services.job_process import JobContext
from softsig_service.services.serialize import to_jsonable

MODEL_SETTINGS = frozenset({"hands_dir", "limits", "robots_dir"})
"""The settings that shape the models a job loads: where the built-in hands and the UR5 are, and the limits."""


def model_settings(settings: Settings) -> dict[str, Any]:
    """The JSON of the :data:`MODEL_SETTINGS` of ``settings``, for a job's private parameters (``settings``)."""
    return settings.model_dump(mode="json", include=set(MODEL_SETTINGS))


def job_settings(params: dict[str, Any]) -> Settings | None:
    """The settings a job runs under: those the service passed in ``params["settings"]`` (see
    :func:`model_settings`), else None (the built-in defaults)."""
    given = params.get("settings")
    return Settings(**given) if given is not None else None


def _compile(manifest_path: str, limits: ModelLimits) -> Any:
    from softsig_service.hands.manifest import load_manifest
    from softsig_service.hands.model import compile_hand

    path = Path(manifest_path)
    manifest = load_manifest(path, max_bytes=limits.max_model_bytes)
    return compile_hand(manifest, path.parent, limits)


def inspect_hand(manifest_path: str, limits: ModelLimits) -> dict[str, Any]:
    """Load a hand from its manifest (every path and size check of the hand library) and summarise it.

    Any failure of a user's model is reported as :class:`InvalidHandModel` (never a server error).
    """
    from softsig_service.hands.summary import hand_info

    try:
        hand = _compile(manifest_path, limits)
        info = hand_info(hand)
    except SoftsigError:
        raise
    except Exception as exc:
        raise InvalidHandModel(f"the model could not be loaded: {type(exc).__name__}: {exc}", field="model") from None
    info.pop("folder", None)  # a server path: not for clients
    return dict(to_jsonable(info))


def closure_signature(
    manifest_path: str, limits: ModelLimits, method: str, criterion: str = "absolute"
) -> dict[str, Any]:
    """Simulate the hand's free closure and compute its closure signature by ``method`` (in the hand's grasp frame,
    which is the hand frame unless its manifest states a ``grasp_frame``); ``criterion`` is the ellipsoid method's
    ("absolute" [m] or "relative")."""
    from softsig_service.hands.closure import in_grasp_frame, simulate_closure
    from softsig_service.hands.summary import closure_summary
    from softsig_service.signatures.closure import compute_closure_signature

    hand = _compile(manifest_path, limits)
    traj = in_grasp_frame(hand, simulate_closure(hand, surface_points=None if method == "mesh" else 0))
    cs = compute_closure_signature(traj, method, criterion=criterion)  # type: ignore[arg-type]
    return {"signature": to_jsonable(cs.to_json_dict()), "closure": to_jsonable(closure_summary(traj))}


def markers_signature(
    text: str, fmt: str, method: str, expected_points: list[str] | None, hand: str, criterion: str = "absolute"
) -> dict[str, Any]:
    """Parse uploaded marker trajectories (CSV ``time,point,x,y,z`` or trajectory JSON; hand frame, metres,
    seconds) and compute the closure signature by ``method`` (``criterion``: the ellipsoid method's)."""
    from softsig_service.hands.summary import closure_summary
    from softsig_service.signatures.closure import compute_closure_signature
    from softsig_service.signatures.markers import parse_markers_csv, parse_markers_json

    if fmt == "csv":
        traj = parse_markers_csv(text, hand=hand, expected_points=expected_points)
    else:
        traj = parse_markers_json(text, expected_points=expected_points)
    cs = compute_closure_signature(traj, method, criterion=criterion)  # type: ignore[arg-type]
    return {"signature": to_jsonable(cs.to_json_dict()), "closure": to_jsonable(closure_summary(traj))}


def run_stiffness_signature(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """The stiffness signature of a hand on an object (docs/design.md §5): grasp in MuJoCo, 6x6 grasp stiffness at the
    object's centre (hand frame, linear first), break forces of the pull test in the default 26 directions.

    ``params``: ``manifest_path``, ``limits`` (the service's model limits) and ``object`` (object JSON). Writes
    ``stiffness_signature.json`` into the job's folder.
    """
    import json

    from softsig_service.objects import object_from_json
    from softsig_service.simulation.stiffness_signature import compute_stiffness_signature

    ctx.progress(0.0, "loading the hand")
    hand = _compile(str(params["manifest_path"]), ModelLimits(**params["limits"]))
    obj = object_from_json(params["object"])
    ctx.progress(0.05, "grasping and pulling")
    ss = compute_stiffness_signature(hand, obj)
    data = to_jsonable(ss.to_json_dict())
    ctx.out_dir.mkdir(parents=True, exist_ok=True)
    (ctx.out_dir / "stiffness_signature.json").write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    ctx.progress(1.0, "done")
    return {"signature": data}


def run_capture_signature(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """The capture model of a hand on an object (strategy R; :mod:`softsig_service.experiments.capture`): grasp
    simulations over a grid of relative poses plus held-out checks, in ``workers`` processes.

    ``params``: ``hand_ref`` (manifest path), ``object`` (object JSON), ``grid`` (``n_theta``, ``half_width``
    [m], ``step`` [m], ``holdout``, ``seed``), ``workers``. Writes ``capture_model.json`` into the job's folder.
    """
    import json

    from softsig_service.experiments.capture import CaptureGrid, build_capture_model

    grid = CaptureGrid(**params["grid"])
    meter = Progress(0)

    def progress(done: int, of: int) -> None:
        meter.total = of
        meter.update(done)
        ctx.progress(meter.fraction, meter.message("simulations"))

    model = build_capture_model(
        str(params["hand_ref"]), params["object"], grid, workers=int(params.get("workers") or 1), progress=progress,
        settings=job_settings(params),
    )  # fmt: skip
    data = to_jsonable(model.to_json_dict())
    ctx.out_dir.mkdir(parents=True, exist_ok=True)
    (ctx.out_dir / "capture_model.json").write_text(json.dumps(data) + "\n", encoding="utf-8")
    return {"signature": data}


def run_validation(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """Validate a plan in MuJoCo (docs/design.md §7): ``trials`` rollouts of :func:`~softsig_service.simulation.rollout.
    run_trial` (plan on the nominal pose, object perturbed by yaw ~ N(0, sigma_r^2) [rad], x, y ~ N(0, sigma_t^2)
    [m]), trial ``k`` seeded as ``softsig validate`` seeds it (same seed, same outcomes).

    ``params``: ``hand_ref`` (name or manifest path), ``object`` (object JSON in ``base_link``), ``table_height``
    [m], ``obstacles`` (object JSON, optional), ``strategy``, ``sigma_r``,
    ``sigma_t``, ``trials``, ``seed``, ``settings`` (:func:`model_settings`), ``keyframes`` (optional). Writes
    ``validation.json`` (every trial's record) and ``outcomes.csv``; with ``keyframes``, a keyframe strip per trial
    (:mod:`softsig_service.simulation.keyframes`), ``keyframes/trial_NNN.png``, listed by URL in the result's
    ``keyframes``.
    """
    import csv
    import json

    from softsig_service.experiments.campaign_spec import trial_seed
    from softsig_service.experiments.trial import run_trial
    from softsig_service.objects import object_from_json

    table = float(params.get("table_height", 0.0))
    obj = object_from_json(params["object"], table_height=table)
    obstacles = [object_from_json(o, table_height=table, field=f"obstacles[{i}]")
                 for i, o in enumerate(params.get("obstacles", []))]  # fmt: skip
    trials, seed = int(params["trials"]), int(params["seed"])
    settings = job_settings(params)
    results = []
    meter = Progress(trials)
    ctx.progress(0.0, meter.message())
    keyframes = None
    if params.get("keyframes"):
        from softsig_service.simulation.keyframes import KeyframeRecorder

        keyframes = KeyframeRecorder()
    strips = []
    try:
        for k in range(trials):
            result = run_trial(
                str(params["hand_ref"]), obj, params["strategy"], seed=trial_seed(seed, (), k),
                sigma_r=float(params["sigma_r"]), sigma_t=float(params["sigma_t"]), settings=settings,
                obstacles=obstacles, on_phase=keyframes,
            )  # fmt: skip
            results.append(result)
            if keyframes is not None:
                setting = f"{params['hand']} / {obj.name or obj.kind} / {params['strategy']}"
                path = keyframes.save_trial(ctx.out_dir / "keyframes", k, result, setting)
                strips.append(f"/v1/jobs/{ctx.job_id}/files/keyframes/{path.name}")
            meter.update(k + 1)
            ctx.progress(meter.fraction, meter.message())
    finally:
        if keyframes is not None:
            keyframes.close()
    outcomes = [
        {"seed": r.seed, "success": r.success, "reason": r.reason, "lift_height": r.lift_height} for r in results
    ]
    data = {
        "hand": params["hand"],
        "object": obj.to_json(),
        "strategy": params["strategy"],
        "sigma_r": float(params["sigma_r"]),
        "sigma_t": float(params["sigma_t"]),
        "seed": seed,
        "trials": trials,
        "successes": sum(r.success for r in results),
        "outcomes": outcomes,
    }
    if keyframes is not None:
        data["keyframes"] = strips
    ctx.out_dir.mkdir(parents=True, exist_ok=True)
    full = {**data, "details": [to_jsonable(r.to_json_dict()) for r in results]}
    (ctx.out_dir / "validation.json").write_text(json.dumps(full, indent=1) + "\n", encoding="utf-8")
    with (ctx.out_dir / "outcomes.csv").open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=["trial", "seed", "success", "reason", "lift_height"])
        writer.writeheader()
        for k, o in enumerate(outcomes):
            writer.writerow({"trial": k, **o})
    return data


def run_experiment(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """The reference experiment (docs/design.md §7, the paper's Table I) with
    :func:`~softsig_service.experiments.campaign.run_campaign`: 3 conditions x 3 objects x S and C x ``trials``,
    in ``workers`` processes (default: the campaign's own choice, every core). Its files (``campaign.json``,
    ``trials.jsonl``, ``results.json``, ``results.csv``, ``report.md``, ``table1.png``) go to the job's folder.

    ``params``: ``hand_ref``, ``trials`` (per cell), ``seed``, ``workers``.
    """
    from softsig_service.experiments.campaign import run_campaign
    from softsig_service.experiments.campaign_spec import CampaignSpec

    spec = CampaignSpec(hand=str(params["hand_ref"]), trials=int(params["trials"]), seed=int(params["seed"]))
    total = len(spec.trial_specs())
    ctx.progress(0.0, f"0 of {total} trials")
    meter = Progress(total)
    first = True

    def progress(done: int, of: int) -> None:
        nonlocal first
        if first:  # the first report follows this run's first trial: what came before was a resumed run's
            meter.start, first = done - 1, False
        meter.update(done)
        ctx.progress(meter.fraction, meter.message())

    result = run_campaign(
        spec, ctx.out_dir, workers=params.get("workers"), progress=progress, settings=job_settings(params)
    )
    return {
        "name": params.get("name", "table1"),
        "hand": params["hand"],
        "trials_per_cell": spec.trials,
        "seed": spec.seed,
        "complete": result.complete,
        "ran": result.ran,
        "skipped": result.skipped,
        "wall_time": result.wall_time,
        "summary": to_jsonable(result.summary),
        "files": sorted(Path(f).name for f in result.files.values()),
    }


def run_calibration(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """A calibration (:func:`~softsig_service.experiments.calibration.calibrate`) of the hand ``hand_ref`` to the
    stored outcomes ``outcomes`` (the route adds them), its files (``calibration.json``, ``evaluations.jsonl``,
    ``report.md``, ``calibration.png``, ``variant/<name>/``) in the job's folder; progress per parameter set."""
    from softsig_service.experiments.calibration import CalibrationSpec, calibrate
    from softsig_service.experiments.calibration_report import write_calibration_report
    from softsig_service.experiments.outcomes import CellSelector, RealOutcomes

    spec = CalibrationSpec(
        hand=str(params["hand_ref"]),
        outcomes=RealOutcomes.model_validate(params["outcomes"]),
        held_out=tuple(CellSelector.model_validate(s) for s in params["held_out"]),
        parameters=tuple(params["parameters"]),
        ranges={k: (float(v[0]), float(v[1])) for k, v in params["ranges"].items()},
        budget=int(params["budget"]),
        trials_per_cell=int(params["trials_per_cell"]),
        test_trials=int(params["test_trials"]),
        seed=int(params["seed"]),
        name=str(params["name"]),
        outcomes_version=params.get("outcomes_version"),
    )
    meter: Progress | None = None

    def progress(done: int, planned: int, message: str) -> None:
        nonlocal meter
        meter = meter or Progress(planned)
        meter.update(done)
        ctx.progress(meter.fraction, f"{message}; {meter.message()}")

    workers = params.get("workers") or 1
    result = calibrate(spec, ctx.out_dir, workers=int(workers), progress=progress, settings=job_settings(params))
    payload = result.to_json_dict()
    files = write_calibration_report(payload, ctx.out_dir)
    return {
        "hand": params["hand"],
        "outcomes_version": spec.outcomes_version,
        "calibrated": payload["calibrated"],
        "defaults": payload["defaults"],
        "parameters": payload["parameters"],
        "heldout_loglik": payload["heldout_loglik"],
        "fitted_loglik": payload["fitted_loglik"],
        "simulations": payload["simulations"],
        "wall_time": payload["wall_time"],
        "variant_folder": str(result.variant.parent) if result.variant else None,
        "variant_name": spec.name,
        "files": sorted(
            ["calibration.json", "evaluations.jsonl", Path(files["report"]).name, Path(files["figure"]).name]
        ),
    }
