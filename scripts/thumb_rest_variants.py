"""Diagnostic: copies of hands/pisa_iit_softhand with another thumb rest pose (guesses, never the default model).

The published description fixes the thumb's joints but not how it rests on a real robot; docs/experiment_table1.md
(point 8 of "Why S loses the nominal box and cylinder") uses these copies to test whether the rest pose explains why
strategy S drops the nominal box and cylinder.


Why not springref alone: the motor is a bilateral position servo on the synergy tendon (L = sum R_j q_j held at 0
for u = 0, stiffness 1 N*m/rad on L), so a spring reference theta0 on thumb_abd (E = 0.2) would be mostly cancelled
by the servo (q ~ 0.2*theta0/(0.2 + 1.3^2) ~ 0.1*theta0) and would also move the finger abductions. A real tendon
is slack at rest. So the rest offset is implemented as the equivalent "spring reference + tendon zero moved to
the rest": the joint's parent frame is rotated about the joint axis by theta0, so q = 0 (spring rest, tendon zero,
motor u = 0) is the new rest pose. The joint range keeps the published convention (rest at the lower limit) and
the published absolute upper limit: relative range [0, hi - theta0].

Variants:
  thumb_copy           control, unchanged
  thumb_abd_{p,m}{02,04} thumb_abd rest offset +-0.2/0.4 rad: theta0 (rad; + = the published closing
                       direction, thumb across palm)
  thumb_swing_{w04,w08,f04}  the whole thumb (knuckle frame, hence its abduction axis) swung about the palm normal
                       (hand z) through its base by 0.4 / 0.8 rad toward the wrist (w, tip to hand +y)
                       or 0.4 rad toward the fingers (f); _abd_p0{2,4}: plus the abduction rest offset; this is a
                       change of the base orientation, not of a joint's rest
  thumb_abd_p0{2,4}_prox_m02 abduction rest +0.2/+0.4 and both thumb_prox halves extended by 0.2 rad at rest
  thumb_prox_{02,04}   thumb_prox_1 and thumb_prox_2 each flexed by theta at rest (the pair 2*theta)
Usage: python scripts/thumb_rest_variants.py --out DIR [names...]   (default: every variant)
Then, e.g.: python scripts/guarded_approach.py --hand DIR/thumb_swing_w04/hand.toml --fc none --out w04.jsonl
"""

from __future__ import annotations

import argparse
import re
import shutil
from pathlib import Path

import mujoco
import numpy as np

SRC = Path(__file__).resolve().parent.parent / "hands" / "pisa_iit_softhand"


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, np.asarray(a, float), np.asarray(b, float))
    return out


def axquat(axis: tuple[float, float, float], ang: float) -> np.ndarray:
    out = np.zeros(4)
    mujoco.mju_axisAngle2Quat(out, np.asarray(axis, float), ang)
    return out


def fmt(q: np.ndarray) -> str:
    return " ".join(f"{v:.10f}" for v in q)


def rot_body(text: str, body: str, axis: tuple[float, float, float], ang: float) -> str:
    """Rotate body's frame about its own origin (its joint's position) by ang about axis (body frame)."""
    pat = re.compile(rf'(<body name="{body}" pos="[^"]*")( quat="([^"]*)")?')
    m = pat.search(text)
    assert m, body
    q0 = np.array([float(v) for v in m.group(3).split()]) if m.group(3) else np.array([1.0, 0, 0, 0])
    q1 = qmul(q0, axquat(axis, ang))
    return text[: m.start()] + f'{m.group(1)} quat="{fmt(q1)}"' + text[m.end() :]


def swing_body(text: str, body: str, axis_parent: tuple[float, float, float], ang: float) -> str:
    """Rotate body's frame about an axis given in its PARENT frame, through the body's origin."""
    pat = re.compile(rf'(<body name="{body}" pos="[^"]*")( quat="([^"]*)")?')
    m = pat.search(text)
    assert m, body
    q0 = np.array([float(v) for v in m.group(3).split()]) if m.group(3) else np.array([1.0, 0, 0, 0])
    q1 = qmul(axquat(axis_parent, ang), q0)
    return text[: m.start()] + f'{m.group(1)} quat="{fmt(q1)}"' + text[m.end() :]


def set_range(text: str, joint: str, lo: float, hi: float, extra: str = "") -> str:
    pat = re.compile(rf'(<joint name="{joint}" class="(abd|roll)")([^/]*)/>')
    m = pat.search(text)
    assert m, joint
    attrs = re.sub(r'\s*range="[^"]*"', "", m.group(3))
    new = f'{m.group(1)}{attrs} range="{lo:.8f} {hi:.8f}"{extra}/>'
    return text[: m.start()] + new + text[m.end() :]


def make(out: Path, name: str, abd: float = 0.0, prox: float = 0.0, swing: float = 0.0) -> None:
    dst = out / name
    if dst.exists():
        shutil.rmtree(dst)
    shutil.copytree(SRC, dst, ignore=shutil.ignore_patterns("capture"))
    xml = dst / "pisa_iit_softhand.xml"
    t = xml.read_text()
    if swing:
        # swing the whole thumb (knuckle frame and its abduction axis) about the palm normal (palm +x = hand +z)
        # through the thumb base; + = toward the wrist (hand +y)
        t = swing_body(t, "thumb_knuckle", (1, 0, 0), -swing)  # about palm +x; -angle = tip toward hand +y
    if abd:
        t = rot_body(t, "thumb_knuckle", (0, 0, -1), abd)
        t = set_range(t, "thumb_abd", 0.0, np.pi / 2 - abd)
    if prox:
        for b, j in (("thumb_prox_roll", "thumb_prox_1"), ("thumb_prox", "thumb_prox_2")):
            t = rot_body(t, b, (0, -1, 0), prox)
            t = set_range(t, j, 0.0, np.pi / 4 - prox)  # prox < 0: extension, relative range [0, pi/4 + |prox|]
    xml.write_text(t)
    toml = dst / "hand.toml"
    s = toml.read_text()
    s = re.sub(r'^name = ".*"$', f'name = "pisa_iit_softhand_{name}"', s, count=1, flags=re.M)
    toml.write_text(s)
    print(dst, "abd", abd, "prox", prox, "swing", swing)


VARIANTS = {
    "thumb_copy": {},
    "thumb_abd_p02": {"abd": 0.2},
    "thumb_abd_p04": {"abd": 0.4},
    "thumb_abd_m02": {"abd": -0.2},
    "thumb_abd_m04": {"abd": -0.4},
    "thumb_prox_02": {"prox": 0.2},
    "thumb_prox_04": {"prox": 0.4},
    # second round: toward the wrist side (hand +y)
    "thumb_swing_w04": {"swing": 0.4},
    "thumb_swing_w08": {"swing": 0.8},
    "thumb_swing_f04": {"swing": -0.4},
    "thumb_swing_w04_abd_p02": {"swing": 0.4, "abd": 0.2},
    "thumb_swing_w04_abd_p04": {"swing": 0.4, "abd": 0.4},
    "thumb_abd_p04_prox_m02": {"abd": 0.4, "prox": -0.2},
    "thumb_abd_p02_prox_m02": {"abd": 0.2, "prox": -0.2},
    # third round: thumb rolling-joint extension alone / with the abduction rest
    "thumb_prox_m02": {"prox": -0.2},
    "thumb_prox_m04": {"prox": -0.4},
    "thumb_abd_p02_prox_m04": {"abd": 0.2, "prox": -0.4},
    # fourth round: swing threshold
    "thumb_swing_w02": {"swing": 0.2},
    "thumb_swing_w06": {"swing": 0.6},
    "thumb_swing_w02_abd_p02": {"swing": 0.2, "abd": 0.2},
    # fifth round: between the 5/6 variants
    "thumb_swing_w03": {"swing": 0.3},
    "thumb_swing_w03_abd_p02": {"swing": 0.3, "abd": 0.2},
    "thumb_abd_p04_prox_m04": {"abd": 0.4, "prox": -0.4},
}

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="folder for the hand copies")
    ap.add_argument("names", nargs="*", help=f"variants (default: all): {', '.join(VARIANTS)}")
    args = ap.parse_args()
    unknown = sorted(set(args.names) - set(VARIANTS))
    if unknown:
        ap.error(f"unknown variants: {', '.join(unknown)}")
    args.out.mkdir(parents=True, exist_ok=True)
    for n in args.names or list(VARIANTS):
        make(args.out, n, **VARIANTS[n])
