"""The capture model from MuJoCo simulations: the parallel gripper on a box against its geometry, and a campaign
that runs strategy R with a stored capture model."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from softsig_service.errors import InvalidInput
from softsig_service.experiments.campaign import run_campaign
from softsig_service.experiments.campaign_spec import CampaignSpec
from softsig_service.experiments.capture import (
    CaptureGrid,
    matching_shipped_capture,
    shipped_capture_path,
    simulate_relative_yaw,
)
from softsig_service.objects import builtin_object
from softsig_service.signatures.capture import CaptureModel, theta_axis, uniform_axis

JAW_HALF_OPENING = 0.0425  # [m] the gripper's 85 mm stroke (hands/parallel_gripper/README.md)
BOX_HALF_WIDTH = 0.03  # [m] the built-in box is 0.06 m wide (docs/design.md §7)


def test_the_grippers_capture_of_a_box_follows_its_jaws() -> None:
    """With the box across the jaws (theta = 0), an offset along the closing axis (hand y, ``v``) within the
    clearance (jaw half-opening minus half the box width, 12.5 mm) is carried; one that puts the box's centre
    beyond a jaw is not; an offset along the box (``u``) does not matter within its length."""
    clearance = JAW_HALF_OPENING - BOX_HALF_WIDTH
    inside = [(0.0, 0.0), (0.0, clearance - 0.0025), (0.0, -(clearance - 0.0025)), (0.04, 0.0), (-0.04, 0.0)]
    beyond = [(0.0, JAW_HALF_OPENING + 0.005), (0.0, -(JAW_HALF_OPENING + 0.005))]
    samples = simulate_relative_yaw("parallel_gripper", builtin_object("box").to_json(), 0.0, inside + beyond, {})
    carried = {(u, v): c for _, u, v, c in samples}
    assert all(carried[o] for o in inside), carried
    assert not any(carried[o] for o in beyond), carried
    # across the jaws the box (0.16 m long) does not fit the 85 mm stroke
    turned = simulate_relative_yaw(
        "parallel_gripper", builtin_object("box").to_json(), np.pi / 2 - 1e-9, [(0.0, 0.0)], {}
    )
    assert turned[0][3] is False


def test_capture_grid_bounds() -> None:
    with pytest.raises(InvalidInput) as info:
        CaptureGrid(n_theta=1)
    assert info.value.field == "n_theta"
    with pytest.raises(InvalidInput) as info:
        CaptureGrid(half_width=0.005, step=0.01)
    assert info.value.field == "half_width"


def test_a_campaign_runs_r_with_the_stored_capture_model(tmp_path: Path) -> None:
    spec = CampaignSpec(
        hand="parallel_gripper", conditions=((0.2, 0.02),), objects=("box",), strategies=("S", "C", "R"), trials=2,
        seed=3,
    )  # fmt: skip
    th, u = theta_axis(6), uniform_axis(0.03, 0.01)
    T, _, V = np.meshgrid(th, u, u, indexing="ij")
    model = CaptureModel(th, u, u, ((np.abs(T) < 0.1) & (np.abs(V) <= 0.01)).astype(float), {"note": "given"})
    (tmp_path / "capture").mkdir()
    (tmp_path / "capture" / "box.json").write_text(json.dumps(model.to_json_dict()))
    result = run_campaign(spec, tmp_path, workers=1)
    assert result.complete and result.ran == 6
    r = [rec for rec in result.records if rec["strategy"] == "R"]
    assert len(r) == 2 and all(rec["plan_reasons"] == [] for rec in r), r
    assert json.loads((tmp_path / "capture" / "box.json").read_text())["meta"] == {"note": "given"}, "reused"
    pooled = result.summary["pooled"]
    assert pooled["fisher_r"]["versus"] in ("S", "C") and 0.0 <= pooled["fisher_r"]["r_greater"] <= 1.0
    report = (tmp_path / "report.md").read_text()
    assert "Strategy R against the better of S and C" in report


def test_a_campaign_reuses_the_model_shipped_with_the_hand(tmp_path: Path) -> None:
    spec = CampaignSpec(
        hand="parallel_gripper", conditions=((0.1, 0.01),), objects=("box",), strategies=("R",), trials=1, seed=1
    )
    shipped = shipped_capture_path("parallel_gripper", "box")
    assert shipped is not None
    result = run_campaign(spec, tmp_path, workers=1)
    assert result.complete and (tmp_path / "capture" / "box.json").read_text() == shipped.read_text()
    # built for another placement it does not match, and would be built anew
    other = {"cs_method": "ellipsoid", "cs_criterion": "absolute", "placement": "grasp_centre"}
    assert matching_shipped_capture(shipped, builtin_object("box").to_json(), CaptureGrid(), other) is None
