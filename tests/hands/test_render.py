"""The open/closed picture of a hand: two light panels that differ, their names written, the three hand-frame
axes drawn in both (also for the SoftHand, whose palm hides the flange), the CS axis when given and the grasp frame
when the manifest declares one."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from softsig_service.config import Settings
from softsig_service.gl_backend import render_unavailable_reason
from softsig_service.hands.model import HandModel, load_hand
from softsig_service.hands.render import CS_COLOR, render_open_closed
from softsig_service.simulation.hand_signature import hand_closure_signature
from tests.planning.test_grasp_frame import write_gripper_on_bracket

pytestmark = pytest.mark.skipif(render_unavailable_reason() is not None, reason="no OpenGL backend for rendering")

MINI_HAND = Path(__file__).resolve().parent / "data" / "mini_hand" / "hand.toml"
SIZE = 240


def colour_mask(image: NDArray[np.uint8], rgb: tuple[float, float, float], tol: float = 0.12) -> NDArray[np.bool_]:
    """Pixels within ``tol`` (per channel, in [0, 1]) of ``rgb``."""
    return np.asarray(np.all(np.abs(image / 255.0 - np.array(rgb)) < tol, axis=-1), dtype=bool)


def axis_pixels(panel: NDArray[np.uint8]) -> dict[str, int]:
    """How many pixels of the hand frame's red, green and blue and of the CS's orange a panel has."""
    f = panel / 255.0
    r, g, b = f[..., 0], f[..., 1], f[..., 2]
    return {
        "x": int(((r > 0.75) & (g < 0.3) & (b < 0.3)).sum()),
        "y": int(((g > 0.6) & (r < 0.3) & (b < 0.3)).sum()),
        "z": int(((b > 0.75) & (r < 0.35) & (g < 0.45)).sum()),
        "cs": int(colour_mask(panel, CS_COLOR).sum()),
    }


def panels(image: NDArray[np.uint8]) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    assert image.shape == (SIZE, 2 * SIZE, 3) and image.dtype == np.uint8
    return image[:, :SIZE], image[:, SIZE:]


@pytest.fixture(scope="module")
def mini() -> HandModel:
    return load_hand(str(MINI_HAND), Settings())


def test_two_light_panels_that_differ_with_their_names_and_every_axis(mini: HandModel) -> None:
    image = render_open_closed(mini, width=SIZE, height=SIZE, signature=hand_closure_signature(mini))
    opened, closed = panels(image)
    grey = image.mean(axis=2) / 255.0
    assert (grey > 0.97).mean() > 0.5  # a light background, most of the picture
    assert np.all(grey[:3, :3] > 0.97) and np.all(grey[-3:, -3:] > 0.97)
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 100  # shaded hand, coloured axes, text: not flat
    changed = np.any(np.abs(opened.astype(int) - closed.astype(int)) > 40, axis=-1)
    assert changed.mean() > 0.02  # the fingers moved
    for panel in (opened, closed):
        counts = axis_pixels(panel)
        assert min(counts.values()) > 40, counts
        hand = grey[:, :SIZE] < 0.6
        assert hand[int(0.2 * SIZE) : int(0.8 * SIZE)].mean() > 0.08  # the hand fills the middle of the panel
        title = panel[: int(0.14 * SIZE), : int(0.5 * SIZE)].mean(axis=2)
        assert (title < 60).sum() > 30  # "open" / "closed" written in dark ink in the top band
        caption = panel[int(0.86 * SIZE) :].mean(axis=2)
        assert (caption < 120).sum() > 30  # the caption


def test_the_cs_axis_is_drawn_only_when_given(mini: HandModel) -> None:
    bare = render_open_closed(mini, width=SIZE, height=SIZE)
    for panel in panels(bare):
        counts = axis_pixels(panel)
        assert counts["cs"] < 5 and min(counts["x"], counts["y"], counts["z"]) > 40, counts


def test_every_hand_frame_axis_shows_on_the_softhand() -> None:
    hand = load_hand("pisa_iit_softhand", Settings())
    image = render_open_closed(hand, width=SIZE, height=SIZE, signature=hand_closure_signature(hand))
    for panel in panels(image):
        counts = axis_pixels(panel)
        assert min(counts.values()) > 40, counts


def test_the_grasp_frame_is_drawn_when_the_manifest_declares_one(tmp_path: Path) -> None:
    bracket = load_hand(write_gripper_on_bracket(tmp_path / "gripper_on_bracket"), Settings())
    assert not np.allclose(bracket.grasp_frame, np.eye(4))
    same = dataclasses.replace(bracket, grasp_frame=np.eye(4))  # the grasp frame where the hand frame is
    with_frame = axis_pixels(panels(render_open_closed(bracket, width=SIZE, height=SIZE))[0])
    without = axis_pixels(panels(render_open_closed(same, width=SIZE, height=SIZE))[0])
    # the grasp frame's thinner x and y arrows add red and green to the hand frame's (its z lies along the
    # hand frame's z, 60 mm up, mostly over it)
    for axis in ("x", "y"):
        assert with_frame[axis] > 1.2 * without[axis], (with_frame, without)
