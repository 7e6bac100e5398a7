"""A calibration's report: the parameters found, the held-out figures and predicted-against-real per cell.

``report.md`` states the parameters (found, default, range and source), the log-likelihoods of the held-out cells
(and of the fitted ones) for the calibrated model, the uncalibrated model and the constant-rate baseline, and a
table per cell (real count with its Wilson 95 % interval, each model's simulated count with its Jeffreys 95 %
interval). ``calibration.png`` draws, per model, each cell's predicted rate against its real rate with both
intervals; held-out cells are filled, fitted ones hollow, the diagonal is a perfect prediction.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

REPORT_MD = "report.md"
FIGURE_PNG = "calibration.png"
MODELS = ("uncalibrated", "calibrated")


def _cell_name(c: dict[str, Any]) -> str:
    return f"{c['object']} {c['strategy']} ({c['sigma_r']:g}, {c['sigma_t']:g})"


def report_markdown(result: dict[str, Any], command: str = "") -> str:
    """The report of a calibration's JSON (:meth:`CalibrationResult.to_json_dict`)."""
    lines = ["# Calibration", ""]
    spec = result["spec"]
    if command:
        lines += ["```bash", command, "```", ""]
    lines += [
        f"Hand `{spec['hand']}`, {result['simulations']} simulations in {result['wall_time']:.0f} s, "
        f"{len(result['evaluations'])} parameter sets, {spec['trials_per_cell']} draws per noisy fitted cell, "
        f"{spec['test_trials']} per noisy held-out cell, seed {spec['seed']}.",
        "",
        "| parameter | calibrated | default | searched | source |",
        "|---|---|---|---|---|",
    ]
    for p in result["parameters"]:
        lo, hi = p["searched_range"]
        lines.append(
            f"| {p['name']} [{p['unit']}] | {p['calibrated']:.4g} | {p['default']:.4g} | [{lo:.4g}, {hi:.4g}] | "
            f"{p['source']} |"
        )
    lines += ["", "Log-likelihood of the real outcomes (beta-binomial; higher is better):", ""]
    lines += ["| model | fitted cells | held-out cells |", "|---|---|---|"]
    held = result["heldout_loglik"]
    for model in (*MODELS, "constant_rate"):
        h = f"{held[model]:.2f}" if model in held else "–"
        lines.append(f"| {model.replace('_', ' ')} | {result['fitted_loglik'][model]:.2f} | {h} |")
    if held:
        better = held["calibrated"] > held["uncalibrated"]
        lines += [
            "",
            f"On the held-out cells the calibrated model predicts the real outcomes "
            f"{'better' if better else 'not better'} than the uncalibrated one "
            f"({held['calibrated']:.2f} vs {held['uncalibrated']:.2f}; the constant rate "
            f"{result['constant_rate']:.3f} gives {held['constant_rate']:.2f}).",
        ]
    lines += [
        "",
        "| cell | split | real | uncalibrated | calibrated |",
        "|---|---|---|---|---|",
    ]
    for c in result["cells"]:
        k, n = c["real"]
        lo, hi = c["real_interval"]
        row = [_cell_name(c), "held out" if c["held_out"] else "fitted", f"{k}/{n} [{lo:.2f}, {hi:.2f}]"]
        for model in MODELS:
            s, m = c["simulated"][model]
            a, b = c["predicted_interval"][model]
            row.append(f"{s}/{m} [{a:.2f}, {b:.2f}]")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def plot_calibration(result: dict[str, Any], path: Path) -> Path:
    """``calibration.png``: predicted against real success rate per cell, one panel per model (module
    docstring)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(MODELS), figsize=(10, 4.8), sharex=True, sharey=True, layout="constrained")
    colours = {"S": "tab:blue", "C": "tab:orange", "R": "tab:green"}
    markers = {"box": "s", "apple": "o", "cylinder": "^"}
    for ax, model in zip(axes, MODELS, strict=True):
        ax.plot([0, 1], [0, 1], color="0.6", lw=1, ls="--", zorder=0)
        for c in result["cells"]:
            k, n = c["real"]
            x = k / n
            y = c["predicted"][model]
            xlo, xhi = c["real_interval"]
            ylo, yhi = c["predicted_interval"][model]
            colour = colours.get(c["strategy"], "0.3")
            ax.errorbar(
                x,
                y,
                xerr=[[x - xlo], [xhi - x]],
                yerr=[[y - ylo], [yhi - y]],
                fmt="none",
                ecolor=colour,
                alpha=0.5,
                lw=1,
            )
            ax.plot(
                x, y, markers.get(c["object"], "D"), ms=8, mec=colour, mew=1.5, mfc=colour if c["held_out"] else "white"
            )
        ll = result["heldout_loglik"].get(model)
        title = f"{model}" + (f": held-out log-likelihood {ll:.1f}" if ll is not None else "")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("real success rate (Wilson 95 %)")
        ax.set_xlim(-0.03, 1.03)
        ax.set_ylim(-0.03, 1.03)
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("simulated success rate (Jeffreys 95 %)")
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], ls="", marker=mk, color="0.3", label=o) for o, mk in markers.items()]
    handles += [
        Line2D([], [], ls="", marker="o", mfc=c, mec=c, label=f"strategy {s}")
        for s, c in colours.items()
        if any(cell["strategy"] == s for cell in result["cells"])
    ]
    handles += [
        Line2D([], [], ls="", marker="o", mfc="0.3", mec="0.3", label="held out"),
        Line2D([], [], ls="", marker="o", mfc="white", mec="0.3", label="fitted"),
    ]
    fig.legend(handles=handles, loc="outside right center", fontsize=9, frameon=False)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_calibration_report(result: dict[str, Any], out: Path, command: str = "") -> dict[str, Path]:
    """Write ``report.md`` and ``calibration.png`` into ``out``; returns their paths."""
    out = Path(out)
    md = out / REPORT_MD
    md.write_text(report_markdown(result, command), encoding="utf-8")
    return {"report": md, "figure": plot_calibration(result, out / FIGURE_PNG)}
