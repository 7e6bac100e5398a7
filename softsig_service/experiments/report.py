"""The report of a campaign: a Markdown table laid out like the paper's Table I beside its real-robot counts, the
failure reasons, a bar chart (matplotlib, Agg), the records as CSV, and the files that hold them.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from softsig_service.experiments.campaign_spec import (
    CHART_PNG,
    PAPER_TABLE1,
    PAPER_TRIALS,
    REPORT_MD,
    RESULTS_CSV,
    RESULTS_JSON,
    TABLE1_CONDITIONS,
    TRIALS_FILE,
    CampaignSpec,
    Condition,
)
from softsig_service.experiments.statistics import fisher_p, summarize

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


def _cond_label(cond: Condition) -> str:
    return f"σr={cond[0]:g} rad, σt={cond[1]:g} m"


def paper_cell(cond: Condition, obj: str) -> dict[str, Any] | None:
    """The paper's real-robot counts of one cell, found by the condition's (sigma_r, sigma_t) (not by its place in a
    campaign's list, so any subset of the conditions finds them): ``S``, ``C``, ``trials`` and ``fisher`` (S vs C);
    None for a condition or an object the paper did not run."""
    rows = PAPER_TABLE1.get(obj)
    for i, paper_cond in enumerate(TABLE1_CONDITIONS):
        if rows is not None and all(math.isclose(a, b, abs_tol=1e-12) for a, b in zip(cond, paper_cond, strict=True)):
            s, c = rows[i]
            return {"S": s, "C": c, "trials": PAPER_TRIALS, "fisher": fisher_p(s, PAPER_TRIALS, c, PAPER_TRIALS)}
    return None


def _ci(d: Mapping[str, Any]) -> str:
    lo, hi = d["wilson95"]
    return f"{d['successes']}/{d['trials']} [{lo:.2f}, {hi:.2f}]"


def report_markdown(spec: CampaignSpec, summary: Mapping[str, Any], wall_time: float | None = None) -> str:
    """The Markdown report: Table I layout (ours and the paper's), intervals, p-values, failure reasons."""
    lines = [f"# Validation campaign: {spec.hand}", ""]
    lines.append(
        f"{spec.trials} trials per cell, campaign seed {spec.seed}, objects at x = {spec.x} m, "
        f"y = {spec.y} m, yaw = {spec.yaw} rad (nominal). Closure signature: {spec.cs_method} method"
        f"{', ' + spec.criterion + ' criterion' if spec.cs_method == 'ellipsoid' else ''}; placement: "
        f"{spec.placement}."
    )
    if wall_time is not None:
        lines.append(f"Wall time of the last run: {wall_time:.1f} s.")
    lines += ["", f"## Successes, {' / '.join(spec.strategies)} (out of N per cell)", ""]
    header = "| object | " + " | ".join(_cond_label(c) for c in spec.conditions) + " |"
    lines += [header, "|---" * (len(spec.conditions) + 1) + "|"]
    cells = {(c["condition"], c["object"]): c for c in summary["cells"]}
    for obj in spec.objects:
        row = [obj]
        for i in range(len(spec.conditions)):
            c = cells[(i, obj)]
            row.append(" / ".join(str(c[s]["successes"]) for s in spec.strategies) + f" (N={spec.trials})")
        lines.append("| " + " | ".join(row) + " |")
    paper = {(i, obj): paper_cell(cond, obj) for i, cond in enumerate(spec.conditions) for obj in spec.objects}
    paper_objects = [obj for obj in spec.objects if any(paper[(i, obj)] for i in range(len(spec.conditions)))]
    if paper_objects:
        lines += [
            "",
            f"## The paper's real-robot counts, S / C (out of {PAPER_TRIALS})",
            "",
            header,
            "|---" * (len(spec.conditions) + 1) + "|",
        ]
        for obj in paper_objects:
            counts = [paper[(i, obj)] for i in range(len(spec.conditions))]
            lines.append("| " + obj + " | " + " | ".join(f"{p['S']} / {p['C']}" if p else "–" for p in counts) + " |")
    if {"S", "C"} <= set(spec.strategies):
        lines += [
            "",
            "## Per cell: Wilson 95 % intervals and Fisher's exact test (S vs C)",
            "",
            "| condition | object | S (succ/N [95 % CI]) | C (succ/N [95 % CI]) | p two-sided | p (C > S) "
            "| paper p two-sided | paper p (C > S) |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for c in summary["cells"]:
            pp = (paper[(c["condition"], c["object"])] or {}).get("fisher")
            paper_cols = f"{pp['two_sided']:.3g} | {pp['c_greater']:.3g}" if pp else "– | –"
            lines.append(
                f"| {_cond_label(spec.conditions[c['condition']])} | {c['object']} | {_ci(c['S'])} | "
                f"{_ci(c['C'])} | {c['fisher']['two_sided']:.3g} | {c['fisher']['c_greater']:.3g} | "
                f"{paper_cols} |"
            )
        lines += [
            "",
            "## Pooled over objects",
            "",
            "| condition | S | C | p two-sided | p (C > S) |",
            "|---|---|---|---|---|",
        ]
        for p in summary["pooled_per_condition"]:
            lines.append(
                f"| {_cond_label(spec.conditions[p['condition']])} | {_ci(p['S'])} | {_ci(p['C'])} | "
                f"{p['fisher']['two_sided']:.3g} | {p['fisher']['c_greater']:.3g} |"
            )
        o = summary["pooled"]
        lines.append(
            f"| all | {_ci(o['S'])} | {_ci(o['C'])} | {o['fisher']['two_sided']:.3g} | {o['fisher']['c_greater']:.3g} |"
        )
    if "R" in spec.strategies and len(spec.strategies) > 1:
        lines += _r_section(spec, summary)
    lines += ["", "## Failure reasons", "", "| condition | object | strategy | reasons |", "|---|---|---|---|"]
    for c in summary["cells"]:
        for s in spec.strategies:
            rs = ", ".join(f"{k} {v}" for k, v in sorted(c["reasons"][s].items())) or "–"
            lines.append(f"| {_cond_label(spec.conditions[c['condition']])} | {c['object']} | {s} | {rs} |")
    lines += ["", f"Chart: `{CHART_PNG}`.", ""]
    return "\n".join(lines)


def _r_section(spec: CampaignSpec, summary: Mapping[str, Any]) -> list[str]:
    """R against the better of S and C per cell, pooled per condition and overall (Fisher, one-sided: R better)."""
    others = [s for s in ("S", "C") if s in spec.strategies]
    lines = [
        "",
        "## Strategy R against the better of " + " and ".join(others) + " (Wilson 95 %, Fisher's exact test)",
        "",
        "| condition | object | " + " | ".join(others) + " | R | versus | p two-sided | p (R > versus) |",
        "|---|---|" + "---|" * len(others) + "---|---|---|---|",
    ]

    def row(label: str, obj: str, d: Mapping[str, Any]) -> str:
        f = d["fisher_r"]
        cols = " | ".join(_ci(d[s]) for s in others)
        return (
            f"| {label} | {obj} | {cols} | {_ci(d['R'])} | {f['versus']} | {f['two_sided']:.3g} | "
            f"{f['r_greater']:.3g} |"
        )

    for c in summary["cells"]:
        lines.append(row(_cond_label(spec.conditions[c["condition"]]), c["object"], c))
    for p in summary["pooled_per_condition"]:
        lines.append(row(_cond_label(spec.conditions[p["condition"]]), "pooled", p))
    lines.append(row("all", "pooled", summary["pooled"]))
    return lines


STRATEGY_COLORS: dict[str, str] = {"S": "#9e9e9e", "C": "#d95f02", "R": "#1b9e77"}
ZERO_BAR_GID = "zero-bar"
"""The ``gid`` of the stub (and of its "0") drawn where a bar of the chart is at zero successes."""
ZERO_BAR_HEIGHT = 0.015
"""Height of that stub, in success rate (the axis runs 0 to 1.05)."""


def summary_figure(spec: CampaignSpec, summary: Mapping[str, Any]) -> Figure:
    """The chart of :func:`plot_summary` as a matplotlib ``Figure`` (Agg canvas, constrained layout): one panel per
    object, a group of bars per condition."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    cells = {(c["condition"], c["object"]): c for c in summary["cells"]}
    panel_width = 1.4 + 0.3 * len(spec.conditions) * len(spec.strategies)
    fig = Figure(figsize=(max(panel_width * len(spec.objects) + 1.3, 4.5), 3.9), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(spec.objects), sharey=True, squeeze=False)[0]
    for ax, obj in zip(axes, spec.objects, strict=True):
        _panel(ax, spec, [cells[(i, obj)] for i in range(len(spec.conditions))], obj)
    axes[0].set_ylabel("success rate")
    fig.supxlabel("object-pose noise: σr of the yaw, σt of x and y (standard deviations)", fontsize=8)
    handles: dict[str, Any] = {}
    for ax in axes:  # every panel's entries: a panel may lack the paper's markers (an object the paper did not run)
        for h, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, h)
    rank = {s: k for k, s in enumerate(spec.strategies)}
    order = sorted(handles, key=lambda label: ("paper" in label, rank[label.split()[0]]))  # sim first
    fig.legend([handles[k] for k in order], order, fontsize=7, loc="outside right center", frameon=False)
    title = " vs ".join(spec.strategies)
    fig.suptitle(f"{spec.hand}: {title} under pose uncertainty ({spec.trials} trials per bar, Wilson 95 %)",
                 fontsize=9, wrap=True)  # fmt: skip
    return fig


def _panel(ax: Axes, spec: CampaignSpec, cells: Sequence[Mapping[str, Any]], obj: str) -> None:
    """One object's bars (``cells`` in the order of ``spec.conditions``), the paper's S and C as triangles."""
    width = 0.8 / len(spec.strategies)
    x = np.arange(len(spec.conditions))
    paper = [paper_cell(cond, obj) for cond in spec.conditions]
    for k, s in enumerate(spec.strategies):
        color = STRATEGY_COLORS.get(s)
        rates = np.array([c[s]["rate"] or 0.0 for c in cells])
        lo = rates - [c[s]["wilson95"][0] for c in cells]
        hi = np.array([c[s]["wilson95"][1] for c in cells]) - rates
        pos = x - 0.4 + width * (k + 0.5)
        ax.bar(pos, rates, width, color=color, label=f"{s} (sim)", yerr=[lo, hi], capsize=3)
        for z, c in zip(pos, cells, strict=True):
            if c[s]["trials"] and c[s]["successes"] == 0:
                _zero_bar(ax, float(z), width, color)
        rates_paper = [p[s] / p["trials"] if p and s in p else np.nan for p in paper]
        if not np.isnan(rates_paper).all():  # the paper ran S and C only, on Table I's conditions and objects
            ax.plot(pos, rates_paper, "k^" if s == "S" else "kv", markersize=7, markeredgecolor="white",
                    markeredgewidth=0.8, zorder=4, label=f"{s} (paper)")  # fmt: skip
    ax.set_title(obj)
    ax.set_xticks(x)
    ax.set_xticklabels([f"σr = {c[0]:g} rad\nσt = {c[1]:g} m" for c in spec.conditions], fontsize=8)
    ax.set_xlim(-0.5, len(spec.conditions) - 0.5)
    ax.set_ylim(0.0, 1.05)
    ax.grid(axis="y", alpha=0.3)


def _zero_bar(ax: Axes, centre: float, width: float, color: str | None) -> None:
    """A bar at zero successes as a low outlined stub of the bar's width with a "0" over it, beside the error bar."""
    from matplotlib.patches import Rectangle

    ax.add_patch(Rectangle((centre - width / 2, 0.0), width, ZERO_BAR_HEIGHT, facecolor=color, edgecolor="black",
                           linewidth=0.8, clip_on=False, zorder=3, gid=ZERO_BAR_GID))  # fmt: skip
    ax.text(centre - width / 4, ZERO_BAR_HEIGHT + 0.01, "0", ha="center", va="bottom", fontsize=8, color="black",
            gid=ZERO_BAR_GID)  # fmt: skip


def plot_summary(spec: CampaignSpec, summary: Mapping[str, Any], path: Path) -> None:
    """Bar chart of the success rates per object and condition, each strategy with Wilson 95 % error bars, a bar
    at zero drawn as a stub with a "0", the paper's S and C rates as triangles on whichever of its conditions the
    campaign ran, the legend right of the panels (PNG/PDF/SVG by suffix)."""
    fig = summary_figure(spec, summary)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


CSV_COLUMNS: tuple[str, ...] = (
    "index",
    "key",
    "condition",
    "sigma_r",
    "sigma_t",
    "object",
    "strategy",
    "trial",
    "seed",
    "success",
    "reason",
    "lift_height",
    "max_lift",
    "touching_after_close",
    "touching_end",
    "touching_table_end",
    "sag",
    "slip",
    "d_yaw",
    "dx",
    "dy",
    "plan_reasons",
    "arm_collision_time",
    "sim_time",
    "wall_time",
)


def records_csv(records: Sequence[Mapping[str, Any]]) -> str:
    """The records as CSV (one row per trial; units m, rad, s)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in records:
        p = r.get("perturbation", {})
        row = {
            **r,
            "d_yaw": p.get("d_yaw"),
            "dx": p.get("dx"),
            "dy": p.get("dy"),
            "plan_reasons": ";".join(r.get("plan_reasons", [])),
        }
        w.writerow(["" if row.get(c) is None else row.get(c) for c in CSV_COLUMNS])
    return buf.getvalue()


def write_report(
    spec: CampaignSpec, records: Sequence[Mapping[str, Any]], out: Path, wall_time: float | None = None
) -> dict[str, str]:
    """Write ``results.json``, ``results.csv``, ``report.md`` and ``table1.png`` into ``out``; their paths."""
    out.mkdir(parents=True, exist_ok=True)
    summary = summarize(spec, records)
    files = {
        "json": out / RESULTS_JSON,
        "csv": out / RESULTS_CSV,
        "report": out / REPORT_MD,
        "chart": out / CHART_PNG,
        "trials": out / TRIALS_FILE,
    }
    payload = {"campaign": spec.to_json_dict(), "summary": summary, "records": list(records)}
    files["json"].write_text(json.dumps(payload, indent=1) + "\n", encoding="utf-8")
    files["csv"].write_text(records_csv(records), encoding="utf-8")
    files["report"].write_text(report_markdown(spec, summary, wall_time), encoding="utf-8")
    plot_summary(spec, summary, files["chart"])
    return {k: str(v) for k, v in files.items()}
