"""The partial-view grid: the camera's view of each built-in object segments to a solid near the object (its unseen
back shorter, its seen faces where they are), and a small grid runs end to end, pairing each cloud trial with the
exact trial of the same perturbation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from softsig_service.experiments.partial_view import report, run_partial_view, seen_object
from softsig_service.objects import builtin_object


@pytest.mark.parametrize("name", ["box", "apple", "cylinder"])
def test_the_camera_sees_each_object_where_it_is(name: str) -> None:
    seen, depth, cloud, _ = seen_object(name)
    true = builtin_object(name)
    assert depth.shape == (480, 640) and len(cloud) > 100_000
    assert np.linalg.norm(seen.center[:2] - true.center[:2]) < 0.015  # shifted towards the camera at most
    assert abs(seen.height - true.height) < 0.008
    assert seen.extent_major <= true.extent_major + 0.008 and seen.extent_minor <= true.extent_minor + 0.008


def test_a_small_grid_runs_and_pairs_its_trials(tmp_path: Path) -> None:
    summary = run_partial_view(tmp_path, trials=1, objects=("box",), conditions=(1,), workers=1)
    assert set(summary["cells"]) == {f"1/box/{s}/{src}" for s in ("S", "C") for src in ("exact", "cloud")}
    assert all(c["trials"] == 1 for c in summary["cells"].values())
    import json

    records = json.loads((tmp_path / "partial_view.json").read_text())["records"]
    for strategy in ("S", "C"):
        seeds = {r["source"]: r["seed"] for r in records if r["strategy"] == strategy}
        assert seeds["exact"] == seeds["cloud"]  # the same perturbation for both plans
    assert "| 0.1, 0.01 | box |" in report(summary)
