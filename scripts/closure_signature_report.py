"""Print the closure signatures of the built-in hands (three methods x both ellipsoid criteria) as a Markdown
table and draw one figure per hand: open and closed reference points, E_0 and E_T, and the CS of both criteria.

    .venv/bin/python scripts/closure_signature_report.py --out docs/closure_signature

Every number comes from softsig's own closure simulation and closure-signature code (hand frame, metres).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from softsig_service.hands.closure import simulate_closure
from softsig_service.hands.model import builtin_hand_names, load_hand
from softsig_service.signatures.closure import compute_closure_signature
from softsig_service.signatures.closure_types import ClosureSignature


def fmt_vec(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:+.2f}" for x in v) + ")"


def row(hand: str, label: str, cs: ClosureSignature) -> str:
    unit = cs.extras.get("magnitude_unit", "1")
    mag = f"{cs.magnitude * 1000:+.1f} mm" if unit == "m" else f"{cs.magnitude:+.3f}"
    dev = ", ".join(f"{d * 1000:+.1f}" if unit == "m" else f"{d:+.3f}" for d in cs.deformation)
    dist = "≥ 1e5" if cs.distinctness >= 1e5 else f"{cs.distinctness:.2f}"
    tilt = np.degrees(np.arctan2(abs(cs.axis[0]), abs(cs.axis[1])))
    return (
        f"| `{hand}` | {label} | {fmt_vec(cs.axis)} | {tilt:.1f}° | {mag} | {dev}{' mm' if unit == 'm' else ''} | "
        f"{dist} |"
    )


def ellipse_outline(center: np.ndarray, shape: np.ndarray, i: int, j: int, n: int = 100) -> np.ndarray:
    """The outline of the ellipsoid {x: (x-c)^T A (x-c) <= 1} projected on the plane of axes i, j [m]."""
    inv = np.linalg.inv(shape)
    sub = inv[np.ix_([i, j], [i, j])]  # projection of an ellipsoid: the sub-block of A^-1
    w, v = np.linalg.eigh(sub)
    t = np.linspace(0, 2 * np.pi, n)
    pts = (v @ (np.sqrt(np.maximum(w, 0))[:, None] * np.vstack([np.cos(t), np.sin(t)]))).T
    return pts + center[[i, j]]


def figure(hand: str, positions: np.ndarray, sigs: dict[str, ClosureSignature], path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.6))
    p0, pT = positions[0], positions[-1]
    e_abs = sigs["absolute"]
    for ax, (i, j, title) in zip(axes, ((0, 1, "from the approach (hand x, y)"), (1, 2, "from the side (hand y, z)")),
                                 strict=True):  # fmt: skip
        for e, style, label in (
            (e_abs.initial_ellipsoid, "-", "E_0 (open)"),
            (e_abs.final_ellipsoid, "--", "E_T (closed)"),
        ):
            assert e is not None
            o = ellipse_outline(e.center, e.shape, i, j)
            ax.plot(o[:, 0] * 1000, o[:, 1] * 1000, style, color="0.4", lw=1, label=label)
        ax.scatter(p0[:, i] * 1000, p0[:, j] * 1000, c="tab:blue", s=25, label="open points", zorder=3)
        ax.scatter(pT[:, i] * 1000, pT[:, j] * 1000, c="tab:red", s=25, label="closed points", zorder=3)
        c = e_abs.anchor
        scale = 60.0
        for crit, color in (("absolute", "tab:green"), ("relative", "tab:purple")):
            a = sigs[crit].axis
            ax.annotate("", xy=(c[i] * 1000 + scale * a[i], c[j] * 1000 + scale * a[j]),
                        xytext=(c[i] * 1000 - scale * a[i], c[j] * 1000 - scale * a[j]),
                        arrowprops={"arrowstyle": "<->", "color": color, "lw": 2})  # fmt: skip
            ax.plot([], [], color=color, lw=2, label=f"CS, {crit}")
        ax.set_xlabel(f"hand {'xyz'[i]} [mm]")
        ax.set_ylabel(f"hand {'xyz'[j]} [mm]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(f"{hand}: ellipsoid closure signature, both criteria", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=Path("docs/closure_signature"))
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    print("| hand | method | axis (hand frame) | angle from hand y | magnitude | deformation | distinctness |")
    print("|---|---|---|---|---|---|---|")
    for hand in builtin_hand_names():
        h = load_hand(hand)
        traj = simulate_closure(h, surface_points=800)
        sigs = {c: compute_closure_signature(traj, "ellipsoid", criterion=c) for c in ("absolute", "relative")}
        print(row(hand, "ellipsoid, absolute", sigs["absolute"]))
        print(row(hand, "ellipsoid, relative", sigs["relative"]))
        for method in ("pca", "mesh"):
            print(row(hand, method, compute_closure_signature(traj, method)))  # type: ignore[arg-type]
        figure(hand, traj.positions, sigs, args.out / f"{hand}.png")


if __name__ == "__main__":
    main()
