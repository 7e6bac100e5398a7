"""Command-line functions of the validation (typer): ``softsig validate`` and ``softsig experiment table1``.

Registered in ``softsig_service/cli/main.py``::

    from softsig_service.cli.experiments import experiment_app, validate

    app.command("validate")(validate)
    app.add_typer(experiment_app, name="experiment")

Errors: a :class:`~softsig_service.errors.SoftsigError` is printed as one line on stderr and exits with status 2
(as the rest of the CLI does); an interrupted campaign exits with 130 after saying how to resume.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from softsig_service.cli import options as opt
from softsig_service.cli.options import errors_to_exit as _errors
from softsig_service.errors import InvalidInput, RenderUnavailable
from softsig_service.experiments.campaign_spec import plan_option_fields

FRAME_SIZE = (640, 480)
"""Width and height [px] of recorded frames."""


class _Recorder:
    """Renders every frame offscreen (``mujoco.Renderer``) into PNG files (``--all-frames``) and/or a video writer
    (``--video``)."""

    def __init__(self, frames: Path | None, video: Path | None, fps: float) -> None:
        self.frames_dir = frames
        self.video = video
        self.writer: Any = None
        self.renderer: Any = None
        self.count = 0
        self.trial = 0
        self._model: Any = None
        if video is not None:
            try:
                import imageio.v2 as imageio
                import imageio_ffmpeg  # noqa: F401  (the encoder imageio needs for .mp4)
            except ImportError:
                raise InvalidInput(
                    "--video needs a video encoder: pip install imageio imageio-ffmpeg (the 'video' extra); or use "
                    "--frames DIR for a keyframe strip per trial",
                    field="video",
                    value=str(video),
                ) from None
            video.parent.mkdir(parents=True, exist_ok=True)
            self.writer = imageio.get_writer(str(video), fps=fps, macro_block_size=8)
        from softsig_service.gl_backend import render_unavailable_reason

        reason = render_unavailable_reason()
        if reason is not None:
            raise RenderUnavailable(
                "offscreen rendering needs an OpenGL backend (MUJOCO_GL=egl with libegl1, or osmesa): " + reason,
                field="MUJOCO_GL",
            )

    def __call__(self, scene: Any, data: Any) -> None:
        import mujoco

        if self.renderer is None or self._model is not scene.model:
            w, h = FRAME_SIZE
            scene.model.vis.global_.offwidth = max(int(scene.model.vis.global_.offwidth), w)
            scene.model.vis.global_.offheight = max(int(scene.model.vis.global_.offheight), h)
            try:
                self.renderer = mujoco.Renderer(scene.model, height=h, width=w)
            except Exception as exc:  # MuJoCo raises plain RuntimeError kinds for GL failures
                raise RenderUnavailable(f"cannot create an offscreen renderer: {exc}", field="MUJOCO_GL") from None
            self._model = scene.model
        self.renderer.update_scene(data, camera="overview")
        image = self.renderer.render()
        if self.frames_dir is not None:
            from PIL import Image  # Pillow comes with matplotlib

            folder = self.frames_dir / f"trial_{self.trial:03d}"
            folder.mkdir(parents=True, exist_ok=True)
            Image.fromarray(image).save(folder / f"frame_{self.count:05d}.png", compress_level=1)
        if self.writer is not None:
            self.writer.append_data(image)
        self.count += 1

    def next_trial(self) -> None:
        self.trial += 1
        self.count = 0

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
        if self.renderer is not None:
            self.renderer.close()


def validate(
    hand: opt.HandOption,
    obj: opt.ObjectOption,
    x: Annotated[float, typer.Option("--x", help="nominal object centre x in base_link [m]")] = 0.5,
    y: Annotated[float, typer.Option("--y", help="nominal object centre y in base_link [m]")] = 0.0,
    yaw: Annotated[float, typer.Option("--yaw", help="nominal object yaw about world z [rad]")] = 0.0,
    strategy: opt.StrategyOption = "C",
    sigma_r: Annotated[float, typer.Option("--sigma-r", help="std. dev. of the object's yaw offset [rad]")] = 0.0,
    sigma_t: Annotated[float, typer.Option("--sigma-t", help="std. dev. of its x and y offsets [m]")] = 0.0,
    trials: Annotated[int, typer.Option("--trials", help="number of trials", min=1, max=100_000)] = 1,
    seed: Annotated[int, typer.Option("--seed", help="seed; trial k uses SeedSequence(seed, spawn_key=(k,))")] = 0,
    as_json: Annotated[bool, typer.Option("--json", help="print JSON")] = False,
    video: Annotated[Path | None, typer.Option("--video", help="write an MP4 of the trials (needs imageio)")] = None,
    frames: Annotated[
        Path | None,
        typer.Option(
            "--frames",
            help="write a keyframe strip per trial, DIR/trial_NNN.png (the scene at the end of "
            "each phase, contact forces drawn)",
        ),
    ] = None,
    all_frames: Annotated[
        Path | None, typer.Option("--all-frames", help="write every frame as PNG into DIR/trial_NNN/ (slow, large)")
    ] = None,
    fps: Annotated[
        float, typer.Option("--fps", help="frames per second of sim time (--video, --all-frames)", min=1.0, max=500.0)
    ] = 30.0,
    cs_method: opt.CsMethodOption = "ellipsoid",
    criterion: opt.CriterionOption = "absolute",
    placement: opt.PlacementOption = "open_centre",
    capture: opt.CaptureOption = None,
) -> None:
    """Plan a top grasp on the nominal object pose and simulate it in MuJoCo, under pose noise if asked (strategy R
    plans for that noise)."""
    with _errors():
        from softsig_service.experiments.campaign_spec import trial_seed
        from softsig_service.experiments.trial import run_trial
        from softsig_service.planning.strategies import STRATEGIES

        if strategy not in STRATEGIES:
            raise InvalidInput("unknown strategy", field="strategy", value=strategy, choices=STRATEGIES)
        nominal = opt.parse_object(obj, x, y, yaw)
        options: dict[str, Any] = dict(plan_option_fields(cs_method, criterion, placement))
        model = opt.read_capture(capture, hand=hand, obj=nominal, strategy=strategy)
        if model is not None:
            options["capture"] = model
        recorder = _Recorder(all_frames, video, fps) if (all_frames is not None or video is not None) else None
        keyframes = None
        if frames is not None:
            from softsig_service.simulation.keyframes import KeyframeRecorder

            keyframes = KeyframeRecorder()
        results, strips = [], []
        try:
            for k in range(trials):
                result = run_trial(
                    hand,
                    nominal,
                    strategy,  # type: ignore[arg-type]
                    seed=trial_seed(seed, (), k),
                    sigma_r=sigma_r,
                    sigma_t=sigma_t,
                    on_frame=recorder,
                    frame_period=1.0 / fps,
                    on_phase=keyframes,
                    plan_options=options,
                )
                results.append(result)
                if recorder is not None:
                    recorder.next_trial()
                if keyframes is not None and frames is not None:
                    setting = f"{result.hand} / {nominal.name or nominal.kind} / {strategy}"
                    strips.append(keyframes.save_trial(frames, k, result, setting))
        finally:
            if recorder is not None:
                recorder.close()
            if keyframes is not None:
                keyframes.close()
        successes = sum(r.success for r in results)
        data: dict[str, Any] = {
            "hand": results[0].hand,
            "object": nominal.to_json(),
            "strategy": strategy,
            "sigma_r": sigma_r,
            "sigma_t": sigma_t,
            "seed": seed,
            "plan_options": {"cs_method": cs_method, "criterion": criterion, "placement": placement},
            "trials": trials,
            "successes": successes,
            "outcomes": [
                {"seed": r.seed, "success": r.success, "reason": r.reason, "lift_height": r.lift_height}
                for r in results
            ],
            "details": [r.to_json_dict() for r in results],
        }
        if video is not None:
            data["video"] = str(video)
        if frames is not None and keyframes is not None:
            data["frames"] = str(frames)
            data["keyframes"] = [str(p) for p in strips]
            data["keyframe_seconds"] = round(keyframes.seconds, 3)
        if all_frames is not None:
            data["all_frames"] = str(all_frames)
        if as_json:
            typer.echo(json.dumps(data, indent=2))
            return
        lines = [
            f"{data['hand']} / {nominal.name or nominal.kind} / strategy {strategy} / sigma_r {sigma_r:g} rad, "
            f"sigma_t {sigma_t:g} m: {successes}/{trials} successes"
        ]
        for r in results:
            verdict = "success" if r.success else f"FAILED: {r.reason}"
            p = r.perturbation
            from softsig_service.simulation.diagnosis import summary as diagnosis_summary
            from softsig_service.simulation.rollout import SETTLE_DROP

            settled = ""
            if r.settle_drop is not None and r.settle_drop > SETTLE_DROP:
                settled = f"  settled {r.settle_drop * 1000:.1f} mm onto the table first"
            lines.append(
                f"  seed {r.seed:>10d}  {verdict:28s} lift {r.lift_height * 1000:6.1f} mm  offset yaw "
                f"{p.d_yaw:+.3f} rad, x {p.dx * 1000:+.1f} mm, y {p.dy * 1000:+.1f} mm  ({r.wall_time:.2f} s)" + settled
            )
            if r.diagnosis:
                lines.append(f"      {diagnosis_summary(r.diagnosis)}")
        if video is not None:
            lines.append(f"  wrote {video}")
        if frames is not None and keyframes is not None:
            lines.append(f"  wrote {len(strips)} keyframe strip{'s' if len(strips) != 1 else ''} into {frames} "
                         f"(rendering {keyframes.seconds:.2f} s)")  # fmt: skip
        if all_frames is not None:
            lines.append(f"  wrote frames into {all_frames}")
        typer.echo("\n".join(lines))


experiment_app = typer.Typer(help="Reference experiments (the paper's Table I).", no_args_is_help=True)


@experiment_app.command("ranking")
def ranking(
    out: Annotated[Path, typer.Option("--out", help="output folder")],
    trials: Annotated[int, typer.Option("--trials", help="trials per grasp", min=1, max=10_000)] = 30,
    k: Annotated[int, typer.Option("--k", help="ranked grasps per plan", min=2, max=12)] = 6,
    hands: Annotated[str, typer.Option("--hands", help="comma-separated hands")] = "pisa_iit_softhand,rbo_hand2",
    condition: Annotated[int, typer.Option("--condition", help="Table I condition index (noise)", min=0, max=2)] = 1,
    seed: Annotated[int, typer.Option("--seed", min=0)] = 0,
    workers: Annotated[int, typer.Option("--workers", min=1, max=64, help="processes")] = 1,
) -> None:
    """Validate every rank of the ranked grasps (success per rank, rank 1 vs rank k) and the calibration of
    grasp_quality (docs/planning.md); writes ranking.{json,md,png}."""
    with _errors():
        from softsig_service.experiments.ranking import report, run_ranking

        summary = run_ranking(out, hands=tuple(h.strip() for h in hands.split(",") if h.strip()), k=k, trials=trials,
                              condition=condition, seed=seed, workers=workers)  # fmt: skip
        typer.echo(report(summary))
        typer.echo(f"{summary['wall_time']:.0f} s; wrote {out / 'ranking.md'}, {out / 'ranking.json'}, "
                   f"{out / 'ranking.png'}")  # fmt: skip


@experiment_app.command("partial-view")
def partial_view(
    out: Annotated[Path, typer.Option("--out", help="output folder")],
    trials: Annotated[int, typer.Option("--trials", help="trials per cell", min=1, max=10_000)] = 100,
    hand: Annotated[str, typer.Option("--hand", help="built-in name or path to hand.toml")] = "pisa_iit_softhand",
    seed: Annotated[int, typer.Option("--seed", min=0)] = 0,
    workers: Annotated[int, typer.Option("--workers", min=1, max=64, help="processes")] = 1,
) -> None:
    """The Table I grid planned from the simulated depth camera's cloud beside the exact model, validated on the
    true objects (docs/experiment_partial_view.md); writes partial_view.{json,md,png}."""
    from softsig_service.experiments.partial_view import draw_views, report, run_partial_view

    with _errors():
        summary = run_partial_view(out, hand=hand, trials=trials, seed=seed, workers=workers)
        draw_views(out / "partial_view.png")
        typer.echo(report(summary))
        typer.echo(f"wall time {summary['wall_time']:.0f} s; files in {out}")


@experiment_app.command("table1")
def table1(
    out: Annotated[Path, typer.Option("--out", help="output folder (re-run with the same folder to resume)")],
    trials: Annotated[int, typer.Option("--trials", help="trials per cell", min=1, max=10_000)] = 20,
    seed: Annotated[int, typer.Option("--seed", help="campaign seed", min=0)] = 0,
    hand: Annotated[str, typer.Option("--hand", help="built-in name or path to hand.toml")] = "pisa_iit_softhand",
    workers: Annotated[
        int | None, typer.Option("--workers", help="worker processes / Ray CPUs (default: all cores)", min=1)
    ] = None,
    backend: Annotated[str, typer.Option("--backend", help="local | ray")] = "local",
    address: Annotated[str | None, typer.Option("--address", help="Ray cluster address (default: local)")] = None,
    progress: Annotated[bool, typer.Option("--progress/--no-progress", help="progress bar on stderr")] = True,
    as_json: Annotated[bool, typer.Option("--json", help="print the summary as JSON")] = False,
    cs_method: opt.CsMethodOption = "ellipsoid",
    criterion: opt.CriterionOption = "absolute",
    placement: opt.PlacementOption = "open_centre",
    conditions: Annotated[
        str | None,
        typer.Option("--conditions", help="indices of the Table I conditions to run, e.g. 2 or 0,2 (default all)"),
    ] = None,
    strategies: Annotated[
        str,
        typer.Option(
            "--strategies",
            help="comma-separated strategies: S,C (default), or with R (builds the capture models first)",
        ),
    ] = ("S,C"),
    objects: Annotated[
        str,
        typer.Option(
            "--objects",
            help="comma-separated built-in objects: box,apple,cylinder (default, the paper's), or the household "
            "meshes mug, banana, power_drill, mustard_bottle",
        ),
    ] = "box,apple,cylinder",
) -> None:
    """Run the paper's Table I in simulation: 3 uncertainty levels x box, apple, cylinder x S, C (or the grid over
    other built-in objects)."""
    with _errors():
        from softsig_service.experiments.campaign import read_records, run_campaign
        from softsig_service.experiments.campaign_spec import BACKENDS, TABLE1_CONDITIONS, CampaignSpec

        if backend not in BACKENDS:
            raise InvalidInput("unknown backend", field="backend", value=backend, choices=BACKENDS)
        chosen = TABLE1_CONDITIONS
        if conditions is not None:
            try:
                idx = [int(v) for v in conditions.split(",") if v.strip()]
            except ValueError:
                raise InvalidInput("comma-separated integers", field="conditions", value=conditions) from None
            valid = tuple(range(len(TABLE1_CONDITIONS)))
            if not idx or any(i not in valid for i in idx):
                raise InvalidInput("unknown condition index", field="conditions", value=conditions, choices=valid)
            chosen = tuple(TABLE1_CONDITIONS[i] for i in sorted(set(idx)))
        spec = CampaignSpec(
            hand=hand,
            trials=trials,
            seed=seed,
            conditions=chosen,
            strategies=tuple(s.strip() for s in strategies.split(",") if s.strip()),
            objects=tuple(o.strip() for o in objects.split(",") if o.strip()),
            cs_method=cs_method,
            criterion=criterion,
            placement=placement,
        )
        try:
            result = run_campaign(
                spec,
                out,
                workers=workers,
                backend=backend,  # type: ignore[arg-type]
                address=address,
                progress=progress,
            )
        except KeyboardInterrupt:
            n = len(read_records(out / "trials.jsonl"))
            typer.echo(f"interrupted: {n} trials saved in {out}; run the same command again to resume", err=True)
            raise typer.Exit(130) from None
        if as_json:
            typer.echo(
                json.dumps(
                    {
                        "files": result.files,
                        "ran": result.ran,
                        "skipped": result.skipped,
                        "wall_time": result.wall_time,
                        "summary": result.summary,
                    },
                    indent=2,
                )
            )
            return
        typer.echo(Path(result.files["report"]).read_text(encoding="utf-8"))
        typer.echo(
            f"ran {result.ran} trials, skipped {result.skipped} already done, {result.wall_time:.1f} s; "
            f"wrote {', '.join(result.files.values())}"
        )
