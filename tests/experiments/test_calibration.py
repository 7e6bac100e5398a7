"""Calibration to real outcomes: the likelihood, the declared parameters, the uploads, the split, and recovery of
known parameters from outcomes the simulator itself produced."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.errors import InvalidInput, InvalidManifest
from softsig_service.experiments.calibration import CalibrationSpec, calibrate, check_spec, synthetic_outcomes
from softsig_service.experiments.calibration_report import write_calibration_report
from softsig_service.experiments.likelihood import (
    beta_binomial_logpmf,
    binomial_logpmf,
    jeffreys_interval,
    predicted_rate,
)
from softsig_service.experiments.outcomes import CellSelector, RealCell, RealOutcomes, outcomes_from_json, split_cells
from softsig_service.hands.manifest import manifest_from_dict
from softsig_service.hands.model import load_hand
from softsig_service.hands.variant import write_variant

HAND = "pisa_iit_softhand"


# ---------------------------------------------------------------------------------------------------- likelihood


@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 30), s=st.integers(0, 40), extra=st.integers(0, 40))
def test_the_beta_binomial_is_a_distribution_over_real_successes(n: int, s: int, extra: int) -> None:
    m = s + extra
    total = sum(math.exp(beta_binomial_logpmf(k, n, s, m)) for k in range(n + 1))
    assert total == pytest.approx(1.0, abs=1e-9)
    # one real trial: the posterior mean
    assert math.exp(beta_binomial_logpmf(1, 1, s, m)) == pytest.approx(predicted_rate(s, m), rel=1e-12)


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 25), k_frac=st.floats(0, 1), p=st.floats(0.05, 0.95))
def test_many_simulations_make_the_beta_binomial_a_binomial(n: int, k_frac: float, p: float) -> None:
    """With m simulations at a rate p the simulation's noise vanishes as m grows (its effect is O(n^2 / (p m)))."""
    k = round(k_frac * n)
    m = 200_000
    s = round(p * m)
    assert beta_binomial_logpmf(k, n, s, m) == pytest.approx(
        binomial_logpmf(k, n, s / m), abs=n * n / (min(p, 1 - p) * m)
    )


def test_few_simulations_predict_with_less_confidence() -> None:
    """20 of 20 real successes: one successful simulation explains them less than 40 of 40 do."""
    assert beta_binomial_logpmf(20, 20, 1, 1) < beta_binomial_logpmf(20, 20, 40, 40) < 0.0
    lo, hi = jeffreys_interval(5, 10)
    assert lo < 0.5 < hi and jeffreys_interval(50, 100)[1] - jeffreys_interval(50, 100)[0] < hi - lo


# ------------------------------------------------------------------------------------------- declared parameters


def thumb_angles(hand_toml: str) -> tuple[float, float]:
    """(in-plane angle toward the fingers, angle out of the palm plane) [deg] of the open thumb, knuckle to tip,
    in the palm frame."""
    h = load_hand(hand_toml)
    m = h.model
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    palm = m.body("palm").id
    R = d.xmat[palm].reshape(3, 3)
    v = R.T @ (d.site_xpos[m.site("thumb_tip").id] - d.xpos[m.body("thumb_knuckle").id])
    return math.degrees(math.atan2(v[2], v[1])), math.degrees(math.asin(v[0] / np.linalg.norm(v)))


@pytest.mark.parametrize("degrees", [0.0, 25.0, 35.0])
def test_thumb_rest_is_the_published_in_plane_angle(tmp_path: Path, degrees: float) -> None:
    """The SoftHand's thumb_rest is the open thumb's angle toward the fingers in the palm plane: 22 deg as built
    (the description's URDF), and whatever the calibration sets within the published 0-35 deg, the thumb staying
    within 3 deg of the palm plane (../shared/HANDS.md)."""
    base = load_hand(HAND)
    assert thumb_angles(HAND)[0] == pytest.approx(22.0, abs=0.05)
    toml = write_variant(base.folder, base.manifest, tmp_path / "v", "v", {"thumb_rest": math.radians(degrees)}, {})
    in_plane, out_of_plane = thumb_angles(str(toml))
    assert in_plane == pytest.approx(degrees, abs=0.05)
    assert abs(out_of_plane) < 3.0 and out_of_plane == pytest.approx(thumb_angles(HAND)[1], abs=1e-6)


def test_the_stiffness_scale_multiplies_every_joint_spring_and_nothing_else(tmp_path: Path) -> None:
    base = load_hand(HAND)
    toml = write_variant(base.folder, base.manifest, tmp_path / "v", "v", {"joint_stiffness_scale": 1.7}, {})
    v = load_hand(str(toml))
    assert np.allclose(v.model.jnt_stiffness, 1.7 * base.model.jnt_stiffness, rtol=1e-12)
    assert np.array_equal(v.model.body_quat, base.model.body_quat)
    assert np.array_equal(v.model.dof_damping, base.model.dof_damping)
    assert not (tmp_path / "v" / "capture").exists(), "models built on the original stay with it"


def test_values_outside_their_declared_range_or_undeclared_are_refused() -> None:
    data = load_hand(HAND).manifest.model_dump(mode="json", exclude_unset=True)
    for values, needle in (({"thumb_rest": 0.7}, "outside its declared range"), ({"palm_width": 1.0}, "undeclared")):
        bad = {**data, "calibration": {**data["calibration"], "values": values}}
        with pytest.raises(InvalidManifest) as exc:
            manifest_from_dict(bad)
        assert exc.value.field == "calibration" and needle in exc.value.message


# ---------------------------------------------------------------------------------------------- outcomes, spec


def test_bad_uploads_name_the_field() -> None:
    cell = {"object": "box", "strategy": "S", "trials": 20, "successes": 17}
    assert outcomes_from_json({"cells": [cell]}).counts() == {("box", "S", 0.0, 0.0): (17, 20)}
    for bad, field in (
        ({"cells": [{**cell, "successes": 21}]}, "cells[0].successes"),
        ({"cells": [cell, {**cell, "object": "anvil"}]}, "cells[1].object"),
        ({"cells": [{**cell, "strategy": "Z"}]}, "cells[0].strategy"),
        ({"cells": [{**cell, "sigma_t": -0.01}]}, "cells[0].sigma_t"),
        ({"trials": [{"object": "box", "strategy": "C", "success": "maybe"}]}, "trials[0].success"),
        ({"cells": [cell, cell]}, "$"),
        ({}, "$"),
    ):
        with pytest.raises(InvalidInput) as exc:
            outcomes_from_json(bad)
        assert exc.value.field == field, (bad, exc.value)
    trials = outcomes_from_json(
        {"trials": [{"object": "apple", "strategy": "C", "success": ok} for ok in (True, False, True)]}
    )
    assert trials.counts() == {("apple", "C", 0.0, 0.0): (2, 3)}


def paper_like() -> RealOutcomes:
    cells = [
        RealCell(object=o, strategy=s, sigma_r=sr, sigma_t=st_, trials=20, successes=k)
        for (o, s, sr, st_, k) in (
            ("box", "S", 0.0, 0.0, 17),
            ("box", "C", 0.0, 0.0, 20),
            ("box", "S", 0.2, 0.02, 3),
            ("box", "C", 0.2, 0.02, 11),
        )
    ]
    return RealOutcomes(cells=tuple(cells))


def test_the_spec_is_checked_before_anything_runs() -> None:
    base = CalibrationSpec(hand=HAND, outcomes=paper_like(), held_out=(CellSelector(sigma_r=0.2),), budget=100)
    free, defaults, fitted, test, n_sets = check_spec(base)
    assert defaults == {"thumb_rest": pytest.approx(math.radians(22.0), abs=1e-4), "joint_stiffness_scale": 1.0}
    assert {f.parameter.name for f in free} == {"thumb_rest", "joint_stiffness_scale"}
    assert all(k[2] == 0.0 for k in fitted) and all(k[2] == 0.2 for k in test) and n_sets == 50
    for change, field in (
        ({"parameters": ("palm_width",)}, "parameters[0]"),
        ({"ranges": {"thumb_rest": (0.0, 1.0)}}, "ranges.thumb_rest"),
        ({"ranges": {"joint_stiffness_scale": (1.5, 1.2)}}, "ranges.joint_stiffness_scale"),
        ({"budget": 3}, "budget"),
        ({"held_out": (CellSelector(),)}, "held_out"),
        ({"hand": "parallel_gripper"}, "hand"),
    ):
        with pytest.raises(InvalidInput) as exc:
            check_spec(dataclasses.replace(base, **change))  # type: ignore[arg-type]
        assert exc.value.field == field, (change, exc.value)


def test_split_by_selector() -> None:
    keys = sorted(paper_like().counts())
    fitted, test = split_cells(keys, [CellSelector(object="box", strategy="C", sigma_r=0.2)])
    assert test == [("box", "C", 0.2, 0.02)] and len(fitted) == 3


# ----------------------------------------------------------------------------------------------- simulation


def test_a_held_out_cell_never_shapes_the_fit(tmp_path: Path) -> None:
    """The same calibration with the held-out cell's real counts turned from 0/20 to 20/20 evaluates the same
    parameter sets to the same log-likelihoods and picks the same model; only the held-out score moves."""
    fitted = RealCell(object="box", strategy="C", trials=20, successes=20)
    runs = []
    for k in (0, 20):
        held = RealCell(object="cylinder", strategy="C", trials=20, successes=k)
        spec = CalibrationSpec(
            hand=HAND,
            outcomes=RealOutcomes(cells=(fitted, held)),
            held_out=(CellSelector(object="cylinder"),),
            parameters=("thumb_rest",),
            budget=3,
            test_trials=1,
            seed=5,
        )
        runs.append(calibrate(spec, tmp_path / f"k{k}", workers=1).to_json_dict())
    a, b = runs
    assert [e["values"] for e in a["evaluations"]] == [e["values"] for e in b["evaluations"]]
    assert [e["loglik"] for e in a["evaluations"]] == [e["loglik"] for e in b["evaluations"]]
    assert all(c[:4] == ["box", "C", 0.0, 0.0] for e in a["evaluations"] for c in e["cells"])
    assert a["calibrated"] == b["calibrated"] and a["fitted_loglik"] == b["fitted_loglik"]
    assert a["heldout_loglik"]["calibrated"] != b["heldout_loglik"]["calibrated"]
    assert a["split"]["held_out"] == [["cylinder", "C", 0.0, 0.0]]
    variant = load_hand(a["variant"])
    provenance = variant.manifest.calibration.provenance  # type: ignore[union-attr]
    assert provenance["held_out_cells"] == [["cylinder", "C", 0.0, 0.0]]
    assert provenance["fitted_cells"] == [["box", "C", 0.0, 0.0]]


def test_calibration_recovers_the_thumb_rest_the_outcomes_were_simulated_with(tmp_path: Path) -> None:
    """Real outcomes made by the simulator with thumb_rest = 0.05 rad (S carries the nominal box and cylinder
    there, not at the 0.384 rad default): the calibration finds a thumb_rest within 0.15 rad of it (the width of
    the band of angles that give these nominal verdicts, docs/calibration.md), which explains the outcomes better
    than the default, and says so on the held-out cell."""
    truth = 0.05
    cells = [("box", "S", 0.0, 0.0), ("cylinder", "S", 0.0, 0.0), ("box", "C", 0.0, 0.0), ("box", "S", 0.1, 0.01)]
    probe = CalibrationSpec(hand=HAND, outcomes=paper_like())
    outcomes = synthetic_outcomes(probe, {"thumb_rest": truth}, cells, 12, workers=2)
    spec = CalibrationSpec(
        hand=HAND,
        outcomes=outcomes,
        held_out=(CellSelector(sigma_r=0.1),),
        parameters=("thumb_rest",),
        budget=30,
        trials_per_cell=6,
        test_trials=12,
        seed=3,
    )
    result = calibrate(spec, tmp_path / "cal", workers=2)
    found = result.best["thumb_rest"]
    assert abs(found - truth) <= 0.15, result.evaluations
    assert result.fitted_loglik["calibrated"] > result.fitted_loglik["uncalibrated"]
    assert result.heldout_loglik["calibrated"] > result.heldout_loglik["uncalibrated"]
    payload = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    files = write_calibration_report(payload, tmp_path / "cal")
    assert "held-out" in files["report"].read_text()
    from PIL import Image

    image = np.asarray(Image.open(files["figure"]).convert("L"))
    assert image.shape[0] > 300 and image.shape[1] > 600 and image.std() > 10


def test_trials_with_measured_offsets_are_simulated_at_them(tmp_path: Path) -> None:
    """Each real trial whose offset was measured is one simulation at that offset, scored against its own outcome:
    at no offset the nominal box C grasp (carried), 6 cm to the side the hand misses it."""
    trials = [
        {"object": "box", "strategy": "C", "success": True, "offset": {"d_yaw": 0.0, "dx": 0.0, "dy": 0.0}},
        {"object": "box", "strategy": "C", "success": False, "offset": {"d_yaw": 0.0, "dx": 0.0, "dy": 0.06}},
    ]
    spec = CalibrationSpec(
        hand=HAND, outcomes=outcomes_from_json({"trials": trials}), parameters=("thumb_rest",), budget=4, seed=2
    )
    result = calibrate(spec, tmp_path / "cal", workers=1)
    assert len(result.evaluations) == 2
    first = result.evaluations[0]
    assert first["cells"] == [["box", "C", 0.0, 0.0, 1, 2]]  # the two simulations: carried at 0, missed at 6 cm
    # each trial predicted by its own simulation: (1 + 1/2) / 2 for the carried one, the same for the missed one
    assert first["loglik"] == pytest.approx(2 * math.log(0.75), abs=1e-12)


def test_a_range_narrowed_past_the_default_still_scores_the_uncalibrated_model(tmp_path: Path) -> None:
    """With thumb_rest searched in [0, 0.1] rad only, the uncalibrated model (0.384 rad) is simulated apart: S
    drops the nominal box there and carries it at every searched angle (docs/calibration.md's sweep)."""
    spec = CalibrationSpec(
        hand=HAND,
        outcomes=RealOutcomes(cells=(RealCell(object="box", strategy="S", trials=20, successes=17),)),
        parameters=("thumb_rest",),
        ranges={"thumb_rest": (0.0, 0.1)},
        budget=2,
        seed=4,
    )
    result = calibrate(spec, tmp_path / "cal", workers=1).to_json_dict()
    assert all(0.0 <= e["values"]["thumb_rest"] <= 0.1 for e in result["evaluations"])
    (cell,) = result["cells"]
    assert cell["simulated"] == {"uncalibrated": [0, 1], "calibrated": [1, 1]}
    assert result["fitted_loglik"]["uncalibrated"] < result["fitted_loglik"]["calibrated"]
    assert result["simulations"] == 2 + 1  # two searched sets, then the uncalibrated model apart
