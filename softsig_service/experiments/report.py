"""The report of a campaign: a Markdown table laid out like the paper's Table I beside its real-robot counts, the
failure reasons, a bar chart (matplotlib, Agg), the records as CSV, and the files that hold them.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from softsig_service.experiments.campaign_spec import (
    CHART_PNG,
    PAPER_TABLE1,
    REPORT_MD,
    RESULTS_CSV,
    RESULTS_JSON,
    TRIALS_FILE,
    CampaignSpec,
    Condition,
)
from softsig_service.experiments.statistics import summarize


def _cond_label(cond: Condition) -> str:
    return f"σr={cond[0]:g} rad, σt={cond[1]:g} m"


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
    if summary.get("paper_available"):
        lines += [
            "",
            "## The paper's real-robot counts, S / C (out of 20)",
            "",
            header,
            "|---" * (len(spec.conditions) + 1) + "|",
        ]
        for obj in spec.objects:
            if obj in PAPER_TABLE1:
                lines.append("| " + obj + " | " + " | ".join(f"{s} / {c}" for s, c in PAPER_TABLE1[obj]) + " |")
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
            pp = c.get("paper", {}).get("fisher")
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


def plot_summary(spec: CampaignSpec, summary: Mapping[str, Any], path: Path) -> None:
    """Bar chart of the success rates per object and condition, S and C, with Wilson 95 % error bars, and the
    paper's rates as markers (matplotlib ``Figure``, Agg; PNG/PDF/SVG by suffix)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    cells = {(c["condition"], c["object"]): c for c in summary["cells"]}
    fig = Figure(figsize=(3.2 * len(spec.objects) + 2.0, 3.8))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(spec.objects), sharey=True, squeeze=False)[0]
    colors = {"S": "#9e9e9e", "C": "#d95f02", "R": "#1b9e77"}
    width = 0.8 / len(spec.strategies)
    x = np.arange(len(spec.conditions))
    for ax, obj in zip(axes, spec.objects, strict=True):
        for k, s in enumerate(spec.strategies):
            rates, lo, hi, paper = [], [], [], []
            for i in range(len(spec.conditions)):
                d = cells[(i, obj)][s]
                r = d["rate"] or 0.0
                rates.append(r)
                lo.append(r - d["wilson95"][0])
                hi.append(d["wilson95"][1] - r)
                p = cells[(i, obj)].get("paper")
                paper.append(p[s] / p["trials"] if p and s in p else np.nan)
            pos = x - 0.4 + width * (k + 0.5)
            ax.bar(pos, rates, width, color=colors.get(s), label=f"{s} (sim)", yerr=[lo, hi], capsize=3)
            zero = [p_ for p_, r in zip(pos, rates, strict=True) if r == 0.0]
            if zero:  # a bar at zero is drawn as a thick stub with a 0 over it, so that it does not vanish
                ax.plot(zero, [0.004] * len(zero), linestyle="none", marker="_", markersize=width * 40,
                        markeredgewidth=4, color=colors.get(s))  # fmt: skip
                for z in zero:
                    ax.text(z, 0.02, "0", ha="center", va="bottom", fontsize=7, color=colors.get(s))
            if s in ("S", "C"):  # the paper ran S and C only
                ax.plot(pos, paper, "k^" if s == "S" else "kv", markersize=6, label=f"{s} (paper)")
        ax.set_title(obj)
        ax.set_xticks(x)
        ax.set_xticklabels([f"σr = {c[0]:g} rad\nσt = {c[1]:g} m" for c in spec.conditions], fontsize=8)
        ax.set_ylim(0.0, 1.05)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel("success rate")
    handles, labels = axes[-1].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="center right", frameon=False)  # outside the panels
    title = " vs ".join(spec.strategies)
    fig.suptitle(f"{spec.hand}: {title} under pose uncertainty ({spec.trials} trials per bar, Wilson 95 %)", fontsize=9)
    fig.tight_layout(rect=(0.0, 0.0, 0.9, 1.0))
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
