"""The keyframe strip of a trial: one panel per phase boundary reached (an early stop's last), panels not blank and
different, the hand's contact forces drawn where the hand touches the object, forces that balance gravity, a camera
that projects the object where it is rendered; ``softsig validate`` renders only when asked (``--frames``)."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from numpy.typing import NDArray
from PIL import Image
from typer.testing import CliRunner

from softsig_service.cli import app
from softsig_service.experiments.trial import TrialResult, run_trial
from softsig_service.gl_backend import render_unavailable_reason
from softsig_service.objects import builtin_object
from softsig_service.simulation.diagnosis import PHASES
from softsig_service.simulation.keyframes import (
    HAND_FORCE_RGB,
    PANEL_SIZE,
    TITLE_HEIGHT,
    KeyframeRecorder,
    compose_strip,
    geom_corners,
)
from softsig_service.simulation.rollout import Perturbation
from softsig_service.simulation.scene import build_scene
from softsig_service.simulation.scene_model import Scene

pytestmark = pytest.mark.skipif(render_unavailable_reason() is not None, reason="no OpenGL backend for rendering")

W, H = PANEL_SIZE


@dataclass
class Recorded:
    result: TrialResult
    recorder: KeyframeRecorder
    panels: list[Any]
    strip: NDArray[np.uint8]


def record(hand: str, obj: str, strategy: str, seed: int, perturbation: Perturbation | None = None) -> Recorded:
    recorder = KeyframeRecorder()
    try:
        result = run_trial(hand, builtin_object(obj), strategy, seed=seed, perturbation=perturbation,  # type: ignore[arg-type]
                           on_phase=recorder)  # fmt: skip
        panels = list(recorder.panels)
        strip = recorder.compose("test", result.success, result.reason, result.diagnosis)
    finally:
        recorder.close()
    return Recorded(result, recorder, panels, strip)


@pytest.fixture(scope="module")
def gripper_box() -> Recorded:
    """The parallel gripper carries the box (strategy C, no noise)."""
    return record("parallel_gripper", "box", "C", seed=0)


def panel_of(strip: NDArray[np.uint8], k: int) -> NDArray[np.uint8]:
    return strip[TITLE_HEIGHT:, k * W : (k + 1) * W]


def red_pixels(image: NDArray[np.uint8]) -> int:
    """Pixels of the hand's arrow colour."""
    return int(np.all(np.abs(image / 255.0 - np.array(HAND_FORCE_RGB)) < 0.08, axis=-1).sum())


def test_a_carried_box_gives_four_panels_of_the_phase_ends(gripper_box: Recorded) -> None:
    result, strip = gripper_box.result, gripper_box.strip
    assert result.success
    phases = [s["phase"] for s in result.diagnosis["phases"]]
    assert phases == list(PHASES)
    assert [p.snapshot["phase"] for p in gripper_box.panels] == phases
    assert [p.snapshot["time"] for p in gripper_box.panels] == [s["time"] for s in result.diagnosis["phases"]]
    assert strip.shape == (TITLE_HEIGHT + H, len(phases) * W, 3) and strip.dtype == np.uint8
    panels = [panel_of(strip, k) for k in range(len(phases))]
    for panel in panels:
        assert panel.std(axis=(0, 1)).min() > 20.0, "a blank panel"
    for a, b in itertools.pairwise(panels):
        assert np.mean(np.any(np.abs(a.astype(int) - b.astype(int)) > 30, axis=-1)) > 0.01, "two equal panels"
    # the renders themselves: the scene, not a flat colour
    for p in gripper_box.panels:
        assert p.image.shape == (H, W, 3) and p.image.std() > 20.0
    title = strip[:TITLE_HEIGHT]
    assert (title < 100).any(axis=-1).mean() > 0.01, "the title band has text"


def test_the_hand_forces_are_drawn_only_where_the_hand_presses(gripper_box: Recorded) -> None:
    approach, closure, lift, hold = gripper_box.panels
    assert not any(a.from_hand for a in approach.arrows)
    for panel in (closure, lift, hold):
        assert sum(a.from_hand for a in panel.arrows) >= 2
    strip = gripper_box.strip
    assert red_pixels(panel_of(strip, 0)) < 20
    assert all(red_pixels(panel_of(strip, k)) > 150 for k in (1, 2, 3))


def test_the_contact_forces_hold_the_object_against_gravity(gripper_box: Recorded) -> None:
    """Resting on the table (end of the approach) and held still (end of the hold), the contact forces on the
    object sum to its weight, upward: the arrows point the way the forces push the object."""
    scene = build_scene("parallel_gripper", builtin_object("box"))
    weight = float(scene.model.body_subtreemass[scene.object_body]) * 9.81
    for panel in (gripper_box.panels[0], gripper_box.panels[3]):
        total = np.sum([a.force for a in panel.arrows], axis=0)
        np.testing.assert_allclose(total, [0.0, 0.0, weight], atol=0.05 * weight + 0.05)
    table = [a for a in gripper_box.panels[0].arrows if not a.from_hand]
    assert table and all(a.force[2] > 0.0 for a in table)


def test_the_camera_projects_the_object_where_it_is_rendered(gripper_box: Recorded) -> None:
    """With the trial's camera, the object's pixels in a segmentation render (the arm raised out of the way) lie
    inside the projection of its bounding box and fill most of it."""
    obj = builtin_object("box")
    scene: Scene = build_scene("parallel_gripper", obj)
    data = scene.make_data(np.array([np.pi, -np.pi / 2, 0.0, -np.pi / 2, 0.0, 0.0]), obj.primitive_pose)
    camera = gripper_box.recorder.camera
    assert camera is not None
    with mujoco.Renderer(scene.model, height=H, width=W) as renderer:
        renderer.enable_segmentation_rendering()
        renderer.update_scene(data, camera=camera.mjv())
        seg = renderer.render()[..., 0]
    mask = np.isin(seg, scene.object_geoms)
    assert mask.sum() > 500
    px = camera.pixels(geom_corners(scene.model, data, scene.object_geoms), W, H)
    rows, cols = np.nonzero(mask)
    assert cols.min() >= px[:, 0].min() - 2 and cols.max() <= px[:, 0].max() + 2
    assert rows.min() >= px[:, 1].min() - 2 and rows.max() <= px[:, 1].max() + 2
    box = (px[:, 0].max() - px[:, 0].min()) * (px[:, 1].max() - px[:, 1].min())
    assert mask.sum() > 0.4 * box


def test_an_early_stop_ends_the_strip() -> None:
    """The box moved 15 cm from where the gripper was planned to close: the jaws close on nothing, the trial stops
    in the lift with the box out of reach, and the strip's last panel is the stop."""
    rec = record("parallel_gripper", "box", "C", seed=0, perturbation=Perturbation(0.0, 0.15, 0.0))
    phases = [s["phase"] for s in rec.result.diagnosis["phases"]]
    assert rec.result.reason == "no_contact" and phases == ["approach", "closure", "stopped"]
    assert [p.snapshot["phase"] for p in rec.panels] == phases
    assert rec.strip.shape == (TITLE_HEIGHT + H, len(phases) * W, 3)
    for k in range(len(phases)):
        assert panel_of(rec.strip, k).std(axis=(0, 1)).min() > 20.0
    assert not any(a.from_hand for p in rec.panels for a in p.arrows)
    assert all(red_pixels(panel_of(rec.strip, k)) < 20 for k in range(len(phases)))


def test_nothing_simulated_gives_one_grey_panel() -> None:
    strip = compose_strip([], None, "a failed plan: FAILED: unreachable", {})
    assert strip.shape == (TITLE_HEIGHT + H, W, 3)
    middle = panel_of(strip, 0)[H // 3 : 2 * H // 3]
    assert 180 < float(np.median(middle)) < 240


class CountingRenderer(mujoco.Renderer):
    """MuJoCo's renderer, counting how many are created."""

    created = 0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        type(self).created += 1
        super().__init__(*args, **kwargs)


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch) -> Iterator[type[CountingRenderer]]:
    CountingRenderer.created = 0
    monkeypatch.setattr(mujoco, "Renderer", CountingRenderer)
    yield CountingRenderer


def test_validate_renders_only_with_frames(tmp_path: Path, counted: type[CountingRenderer]) -> None:
    runner = CliRunner()
    args = ["validate", "--hand", "parallel_gripper", "--object", "box", "--trials", "2", "--json"]
    plain = runner.invoke(app, args)
    assert plain.exit_code == 0, plain.output
    assert counted.created == 0 and "keyframes" not in plain.output
    out = tmp_path / "strips"
    framed = runner.invoke(app, [*args, "--frames", str(out)])
    assert framed.exit_code == 0, framed.output
    assert counted.created == 1
    assert sorted(p.name for p in out.iterdir()) == ["trial_000.png", "trial_001.png"]
    for p in out.iterdir():
        with Image.open(p) as image:
            assert image.size == (len(PHASES) * W, TITLE_HEIGHT + H)
