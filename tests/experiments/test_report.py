"""The report of a campaign on a subset of the Table I conditions: the paper's counts and p-values found by the
condition's (sigma_r, sigma_t), and the chart (panels, the paper's markers, the legend clear of the panels, a
visible mark for a bar at zero)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import typer
from matplotlib.patches import Rectangle
from typer.testing import CliRunner

from softsig_service.cli.experiments import experiment_app
from softsig_service.experiments.campaign_spec import (
    PAPER_TABLE1,
    PAPER_TRIALS,
    TABLE1_CONDITIONS,
    CampaignSpec,
    Condition,
)
from softsig_service.experiments.report import (
    ZERO_BAR_GID,
    paper_cell,
    plot_summary,
    report_markdown,
    summary_figure,
)
from softsig_service.experiments.statistics import fisher_p, summarize

Successes = Callable[[Condition, str, str, int], int]
"""(condition, object, strategy, trials) -> successes of that cell."""


def _records(spec: CampaignSpec, successes: Successes) -> list[dict[str, Any]]:
    """Records shaped like a campaign's: the first ``successes(...)`` trials of each cell succeed."""
    recs: list[dict[str, Any]] = []
    for t in spec.trial_specs():
        cond = spec.conditions[t.condition]
        ok = t.trial < successes(cond, t.object, t.strategy, spec.trials)
        recs.append({"key": t.key, "index": t.index, "condition": t.condition, "object": t.object,
                     "strategy": t.strategy, "trial": t.trial, "seed": t.seed, "success": ok,
                     "reason": None if ok else "dropped", "lift_height": 0.15 if ok else 0.0,
                     "perturbation": {"d_yaw": 0.0, "dx": 0.0, "dy": 0.0}})  # fmt: skip
    return recs


def _half_but_s_drops_the_box(cond: Condition, obj: str, strategy: str, trials: int) -> int:
    return 0 if (obj, strategy) == ("box", "S") else trials // 2


SUBSETS: list[tuple[tuple[int, ...], tuple[str, ...], tuple[str, ...]]] = [
    ((2,), ("box", "apple", "cylinder"), ("S", "C")),
    ((0, 2), ("box", "apple", "cylinder"), ("S", "C")),
    ((1,), ("cylinder",), ("S", "C")),
    ((1, 2), ("box", "cylinder"), ("S", "C", "R")),
    ((0, 1, 2), ("box", "apple", "cylinder"), ("S", "C")),
]
"""(indices into TABLE1_CONDITIONS, objects, strategies)."""


def _spec(indices: tuple[int, ...], objects: tuple[str, ...], strategies: tuple[str, ...]) -> CampaignSpec:
    conditions = tuple(TABLE1_CONDITIONS[i] for i in indices)
    return CampaignSpec(conditions=conditions, objects=objects, strategies=strategies, trials=4)


def test_paper_cell_is_found_by_the_conditions_values() -> None:
    box = paper_cell((0.2, 0.02), "box")
    assert box is not None and (box["S"], box["C"], box["trials"]) == (3, 11, 20)
    assert box["fisher"]["two_sided"] == pytest.approx(0.0187, abs=1e-3)
    assert box["fisher"]["c_greater"] == pytest.approx(0.00935, abs=1e-4)
    cylinder = paper_cell((0.1, 0.01), "cylinder")
    assert cylinder is not None and (cylinder["S"], cylinder["C"]) == (10, 16)
    assert paper_cell((0.3, 0.03), "box") is None  # not one of the paper's conditions
    assert paper_cell((0.01, 0.1), "box") is None  # sigma_r and sigma_t swapped
    assert paper_cell((0.2, 0.02), "mug") is None  # not one of the paper's objects


@pytest.mark.parametrize(("indices", "objects", "strategies"), SUBSETS)
def test_the_report_has_the_papers_counts_and_p_values_of_the_chosen_conditions(
    indices: tuple[int, ...], objects: tuple[str, ...], strategies: tuple[str, ...]
) -> None:
    spec = _spec(indices, objects, strategies)
    report = report_markdown(spec, summarize(spec, _records(spec, _half_but_s_drops_the_box)))
    assert f"## The paper's real-robot counts, S / C (out of {PAPER_TRIALS})" in report
    for obj in objects:
        row = " | ".join(f"{PAPER_TABLE1[obj][i][0]} / {PAPER_TABLE1[obj][i][1]}" for i in indices)
        assert f"| {obj} | {row} |" in report
    for i in indices:
        sr, st = TABLE1_CONDITIONS[i]
        for obj in objects:
            s, c = PAPER_TABLE1[obj][i]
            p = fisher_p(s, PAPER_TRIALS, c, PAPER_TRIALS)
            line = next(ln for ln in report.splitlines() if ln.startswith(f"| σr={sr:g} rad, σt={st:g} m | {obj} | "))
            assert line.endswith(f"| {p['two_sided']:.3g} | {p['c_greater']:.3g} |"), line
    if 2 in indices and "box" in objects:  # the paper's box at the largest uncertainty, written out
        assert "| σr=0.2 rad, σt=0.02 m | box | 0/4 [0.00, 0.49] | 2/4 [0.15, 0.85] | 0.429 | 0.214 | 0.0187 | 0.00935 |" in report  # fmt: skip
    assert "| – | –" not in report


def test_a_condition_the_paper_did_not_run_has_no_paper_numbers_beside_one_it_ran() -> None:
    spec = CampaignSpec(conditions=((0.3, 0.03), (0.2, 0.02)), objects=("box", "mug"), trials=2)
    report = report_markdown(spec, summarize(spec, _records(spec, _half_but_s_drops_the_box)))
    assert "| box | – | 3 / 11 |" in report
    assert "| mug |" not in report.split("## The paper's real-robot counts")[1].split("## Per cell")[0]
    assert "| σr=0.3 rad, σt=0.03 m | box | 0/2 [0.00, 0.66] | 1/2 [0.09, 0.91] | 1 | 0.5 | – | – |" in report
    assert "| σr=0.2 rad, σt=0.02 m | box | 0/2 [0.00, 0.66] | 1/2 [0.09, 0.91] | 1 | 0.5 | 0.0187 | 0.00935 |" in report  # fmt: skip


def _drawn(spec: CampaignSpec, successes: Successes) -> Any:
    fig = summary_figure(spec, summarize(spec, _records(spec, successes)))
    fig.canvas.draw()
    return fig


@pytest.mark.parametrize(("indices", "objects", "strategies"), SUBSETS)
def test_the_chart_of_a_subset(indices: tuple[int, ...], objects: tuple[str, ...], strategies: tuple[str, ...]) -> None:
    spec = _spec(indices, objects, strategies)
    fig = _drawn(spec, _half_but_s_drops_the_box)
    renderer = fig.canvas.get_renderer()
    assert [ax.get_title() for ax in fig.axes] == list(objects)
    (legend,) = fig.legends
    box = legend.get_window_extent(renderer)
    assert fig.bbox.x0 <= box.x0 and box.x1 <= fig.bbox.x1 and fig.bbox.y0 <= box.y0 and box.y1 <= fig.bbox.y1
    for ax in fig.axes:
        assert not box.overlaps(ax.get_window_extent(renderer)), ax.get_title()
        assert not box.overlaps(ax.get_tightbbox(renderer)), ax.get_title()  # nor their titles and tick labels
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels == [f"{s} (sim)" for s in strategies] + ["S (paper)", "C (paper)"]
    for ax, obj in zip(fig.axes, objects, strict=True):
        ticks = [t.get_text() for t in ax.get_xticklabels()]
        assert ticks == [f"σr = {TABLE1_CONDITIONS[i][0]:g} rad\nσt = {TABLE1_CONDITIONS[i][1]:g} m" for i in indices]
        markers = {ln.get_label(): ln for ln in ax.get_lines() if "paper" in str(ln.get_label())}
        assert set(markers) == {"S (paper)", "C (paper)"}
        for k, s in enumerate(("S", "C")):
            expected = [PAPER_TABLE1[obj][i][k] / PAPER_TRIALS for i in indices]
            np.testing.assert_allclose(np.asarray(markers[f"{s} (paper)"].get_ydata(), dtype=float), expected)


def _zero_marks(ax: Any) -> tuple[list[Rectangle], list[Any]]:
    stubs = [p for p in ax.patches if isinstance(p, Rectangle) and p.get_gid() == ZERO_BAR_GID]
    texts = [t for t in ax.texts if t.get_gid() == ZERO_BAR_GID]
    return stubs, texts


def test_a_bar_at_zero_is_drawn_visibly() -> None:
    spec = _spec((0, 2), ("box", "apple"), ("S", "C"))
    fig = _drawn(spec, _half_but_s_drops_the_box)
    renderer = fig.canvas.get_renderer()
    box_ax, apple_ax = fig.axes
    stubs, texts = _zero_marks(box_ax)
    assert len(stubs) == 2 and [t.get_text() for t in texts] == ["0", "0"]  # S on the box, both conditions
    s_bars = [p for p in box_ax.patches if p.get_gid() != ZERO_BAR_GID and p.get_height() == 0.0]
    assert len(s_bars) == 2  # the bars themselves: zero height, nothing to see
    for stub, bar in zip(sorted(stubs, key=lambda p: p.get_x()), sorted(s_bars, key=lambda p: p.get_x()), strict=True):
        extent = stub.get_window_extent(renderer)
        assert extent.height >= 3.0  # pixels
        assert extent.width == pytest.approx(bar.get_window_extent(renderer).width, abs=1.0)
        assert stub.get_visible() and stub.get_facecolor()[3] > 0
    for t in texts:
        assert box_ax.get_window_extent(renderer).contains(*t.get_window_extent(renderer).p0)
    assert _zero_marks(apple_ax) == ([], [])  # no bar at zero there


def test_no_paper_markers_where_the_paper_did_not_run(tmp_path: Path) -> None:
    spec = CampaignSpec(conditions=((0.3, 0.03),), objects=("box",), trials=2)
    summary = summarize(spec, _records(spec, _half_but_s_drops_the_box))
    fig = summary_figure(spec, summary)
    fig.canvas.draw()
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["S (sim)", "C (sim)"]
    assert not [ln for ln in fig.axes[0].get_lines() if "paper" in str(ln.get_label())]
    plot_summary(spec, summary, tmp_path / "chart.png")
    assert (tmp_path / "chart.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_table1_command_on_one_condition_has_the_papers_numbers(tmp_path: Path) -> None:
    app = typer.Typer(pretty_exceptions_enable=False)
    app.add_typer(experiment_app, name="experiment")
    args = ["experiment", "table1", "--trials", "1", "--seed", "2", "--conditions", "2", "--objects", "box,cylinder",
            "--workers", "1", "--no-progress", "--out", str(tmp_path)]  # fmt: skip
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    report = (tmp_path / "report.md").read_text(encoding="utf-8")
    assert "| box | 3 / 11 |" in report and "| cylinder | 8 / 11 |" in report
    box = next(ln for ln in report.splitlines() if ln.startswith("| σr=0.2 rad, σt=0.02 m | box | "))
    assert box.endswith("| 0.0187 | 0.00935 |")
    assert (tmp_path / "table1.png").stat().st_size > 10_000
