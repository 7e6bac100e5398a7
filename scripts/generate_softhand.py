"""Write the Pisa/IIT SoftHand's MJCF from its published description, for each of its mounts on the UR5 flange:
hands/pisa_iit_softhand/pisa_iit_softhand.xml (in line with the tool axis, through an ATI Gamma force-torque
sensor, the paper's setup, section III.A: the default) and hands/pisa_iit_softhand_bracket/
pisa_iit_softhand_bracket.xml (on a side bracket).

Every number below is either from the published description (Catalano et al., IJRR 33(5), 2014, and the public
ROS description "pisa-iit-soft-hand", BSD-3; see hands/pisa_iit_softhand/README.md) or marked *approximate*.
Run ``python scripts/generate_softhand.py`` after changing a number; the MJCFs are committed.

Frames: the published **palm frame** (right hand: +x out of the palm face, the side the fingers close toward;
+y toward the thumb and index; +z along the fingers) is body ``palm``. The hand frame (body ``mount``, the robot
flange; on the bracket +z out of the palm, +x across the palm from the thumb side to the little finger, fingers
along -y) is softsig's (docs: docs/design.md §3). In line, the flange's +z runs along the fingers (palm axes =
flange axes) and the manifest's ``grasp_frame`` is the bracket's hand frame: the hand is the same in its grasp
frame on both mounts. Lengths in the tables are millimetres, written to the MJCF in metres.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

PI = math.pi
HANDS = Path(__file__).resolve().parents[1] / "hands"

# --- published kinematics (palm frame, mm / rad) -------------------------------------------------------
FINGERS = {  # name: (base position [mm], base rpy [rad], abduction axis, abduction range [rad])
    "thumb": ((5.66972, 29.6160, 55.3140), (0.0, -0.38397275793662144, PI / 2), -1.0, (0.0, PI / 2)),
    "index": ((-3.3, 19.5, 93.6994), (PI / 2, -1.4835299330931884, PI / 2), 1.0, (-PI / 6, PI / 6)),
    "middle": ((-3.3, 0.0, 100.699), (PI, -PI / 2, 0.0), 1.0, (-PI / 6, PI / 6)),
    "ring": ((-3.3, -19.5, 93.6994), (-PI / 2, -1.5184364298870514, -PI / 2), 1.0, (-PI / 6, PI / 6)),
    "little": ((-3.3, -39.0, 83.6994), (-PI / 2, -1.4835299330931884, -PI / 2), 1.0, (-PI / 6, PI / 6)),
}
KNUCKLE = 9.0  # [mm] abduction axis to the first rolling joint (long fingers)
THUMB_KNUCKLE = (22.5, -3.3, 0.0)  # [mm] thumb abduction axis to its inner rolling joint
THUMB_KNUCKLE_ROLL = 0.42662757656587236  # [rad] about x, before the thumb's inner rolling joint
HALF_GAP = 13.0  # [mm] between the two hinges of a rolling joint
PHALANX = 9.0  # [mm] between consecutive rolling joints
TIP = 23.0  # [mm] the pad ends this far beyond the last hinge
FLEX_RANGE = (0.0, PI / 4)  # each half of a rolling joint
# kinematic synergy (the description's mimic multipliers): joint = multiplier * s, s in [0, 1]
SYNERGY = {
    "flex": PI / 4,
    "thumb_abd": 1.3 * PI / 2,
    "thumb_prox": 1.3 * PI / 4,
    "thumb_dist": PI / 4,
    "index_abd": -0.2,
    "middle_abd": 0.0,
    "ring_abd": 0.2,
    "little_abd": 0.4,
}
# adaptive-synergy transmission R (tendon coefficient per joint); the description's R vector
R = {"flex": 1.0, "thumb_abd": 1.3, "thumb_prox": 1.3, "thumb_dist": 1.0,
     "index_abd": -0.2, "middle_abd": 0.0, "ring_abd": 0.2, "little_abd": 0.4}  # fmt: skip
# palm collision shape (palm frame, mm)
PALM = ((-26.8, 11.6), (-49.0, 39.4), (-11.5, 113.4))
MOUNTING_BASE = 53.5  # [mm] hand's mounting base to the palm frame, along -z

# --- physical (v1.2 springs; the rest approximate, see README) -------------------------------------------
E_FLEX = 0.4  # [N·m/rad] rolling-joint half (v1.2)
E_KNUCKLE = 0.8  # [N·m/rad] knuckle (v1.2), used where R = 0 (middle abduction)
F1 = E_FLEX * SYNERGY["flex"] / R["flex"]  # [N·m] tendon force that closes a free flexion half to 45 deg at s=1


def stiffness(joint: str) -> float:
    """Joint stiffness E_j [N·m/rad]: v1.2 springs where they reproduce the kinematic synergy, else
    E_j = R_j F1 / multiplier_j, so that the free-space equilibrium E_j q_j = R_j F reproduces
    q_j = multiplier_j * s with tendon force F = F1 * s."""
    if joint == "middle_abd":
        return E_KNUCKLE
    return R[joint] * F1 / SYNERGY[joint]


MOTOR_STIFFNESS = 1.0  # [N·m/rad] on the tendon coordinate (*approximate*: a stiff, position-controlled motor)
FORCE_FACTOR = 3.0  # largest tendon force = this x F1 (*approximate*)
DAMPING = 0.03  # [N·m·s/rad] (v1.2)
ARMATURE = 1e-4  # [kg·m²] numerical
WIDTH, THICK = 14.0, 18.5  # [mm] phalanx cross-section (across, palm-normal)
MASS = {"knuckle": 0.009, "roll": 0.0005, "phalanx": 0.005, "tip": 0.010, "palm": 0.228}  # [kg]
BASE_MASS = 0.2  # [kg] mounting base and clamp stack (*approximate*)
BRACKET = (70.0, 100.0, 29.0)  # [mm] side bracket on the flange (*approximate*)
# ATI Gamma F/T sensor (standard model): diameter, height [mm], mass [kg], ATI Industrial Automation's published
# Gamma specifications; between the flange and the hand's mounting base, on the tool axis (no adapter plates)
SENSOR = (75.4, 33.3, 0.255)
BITS = {"thumb": 2, "index": 4, "middle": 8, "ring": 16, "little": 32}
PALM_BIT = 64


def rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return Rz @ Ry @ Rx


def quat(Rm: np.ndarray) -> str:
    """wxyz quaternion of a rotation matrix (Shepperd), as an MJCF attribute string."""
    t = np.trace(Rm)
    if t > 0:
        w = math.sqrt(1 + t) / 2
        x, y, z = (Rm[2, 1] - Rm[1, 2]) / (4 * w), (Rm[0, 2] - Rm[2, 0]) / (4 * w), (Rm[1, 0] - Rm[0, 1]) / (4 * w)
    else:
        i = int(np.argmax(np.diag(Rm)))
        j, k = (i + 1) % 3, (i + 2) % 3
        v = [0.0, 0.0, 0.0]
        v[i] = math.sqrt(1 + Rm[i, i] - Rm[j, j] - Rm[k, k]) / 2
        w = (Rm[k, j] - Rm[j, k]) / (4 * v[i])
        v[j] = (Rm[j, i] + Rm[i, j]) / (4 * v[i])
        v[k] = (Rm[k, i] + Rm[i, k]) / (4 * v[i])
        x, y, z = v
    q = np.array([w, x, y, z])
    q /= np.linalg.norm(q) * (1 if q[0] >= 0 else -1)
    return " ".join(f"{c:.10g}" for c in q)


def m(*mm: float) -> str:
    return " ".join(f"{v / 1000:.8g}" for v in mm)


def box(name: str, length: float, mass: float, contype: int, conaffinity: int, cls: str) -> str:
    """A phalanx block from the body origin along +x, ``length`` [mm] long, centred on the joint axis."""
    return (
        f'<geom name="{name}" class="{cls}" type="box" size="{m(length / 2, WIDTH / 2, THICK / 2)}" '
        f'pos="{m(length / 2, 0, 0)}" mass="{mass:g}" contype="{contype}" conaffinity="{conaffinity}"/>'
    )


def finger(name: str) -> str:
    pos, rpy, abd_sign, rng = FINGERS[name]
    bit = BITS[name]
    aff = 1  # objects and the world only: digits pass through one another and the palm (README)
    thumb = name == "thumb"
    abd_joint = "thumb_abd" if thumb else f"{name}_abd"
    lines = [
        f'<body name="{name}_knuckle" pos="{m(*pos)}" quat="{quat(rpy_matrix(*rpy))}">',
        f'  <joint name="{abd_joint}" class="abd" axis="0 0 {abd_sign:g}" range="{rng[0]:.8g} {rng[1]:.8g}" '
        f'stiffness="{stiffness(abd_joint):.8g}"/>',
    ]
    if thumb:
        lines.append("  " + box(f"{name}_knuckle_geom", THUMB_KNUCKLE[0], MASS["knuckle"], bit, aff, "link"))
        segments = [(seg, R[f"thumb_{seg}"], stiffness(f"thumb_{seg}")) for seg in ("prox", "dist")]
        first = (f'pos="{m(*THUMB_KNUCKLE)}" quat="{quat(rpy_matrix(THUMB_KNUCKLE_ROLL, 0, 0))}"', THUMB_KNUCKLE[0])
    else:
        lines.append("  " + box(f"{name}_knuckle_geom", KNUCKLE, MASS["knuckle"], bit, aff, "link"))
        e = stiffness("flex")
        segments = [("prox", R["flex"], e), ("mid", R["flex"], e), ("dist", R["flex"], e)]
        first = (f'pos="{m(KNUCKLE, 0, 0)}"', KNUCKLE)
    depth = 1
    closers = []
    for k, (seg, _r, e) in enumerate(segments):
        ind = "  " * depth
        placement = first[0] if k == 0 else f'pos="{m(PHALANX, 0, 0)}"'
        last = k == len(segments) - 1
        lines += [
            f'{ind}<body name="{name}_{seg}_roll" {placement}>',
            f'{ind}  <joint name="{name}_{seg}_1" class="roll" stiffness="{e:.8g}"/>',
            f"{ind}  {box(f'{name}_{seg}_roll_geom', HALF_GAP, MASS['roll'], bit, aff, 'link')}",
            f'{ind}  <body name="{name}_{seg}" pos="{m(HALF_GAP, 0, 0)}">',
            f'{ind}    <joint name="{name}_{seg}_2" class="roll" stiffness="{e:.8g}"/>',
        ]
        if last:
            lines += [
                f"{ind}    {box(f'{name}_{seg}_geom', TIP, MASS['tip'], bit, aff, 'tip')}",
                f'{ind}    <site name="{name}_tip" pos="{m(TIP, 0, 0)}"/>',
            ]
        else:
            lines.append(f"{ind}    {box(f'{name}_{seg}_geom', PHALANX, MASS['phalanx'], bit, aff, 'link')}")
        closers.append(f"{ind}  </body>\n{ind}</body>")
        depth += 2
    lines += [c for c in reversed(closers)]
    lines.append("</body>")
    return "\n".join(lines)


def tendon_entries() -> list[tuple[str, float]]:
    out: list[tuple[str, float]] = []
    for name in FINGERS:
        if name == "thumb":
            out.append(("thumb_abd", R["thumb_abd"]))
            out += [(f"thumb_prox_{h}", R["thumb_prox"]) for h in (1, 2)]
            out += [(f"thumb_dist_{h}", R["thumb_dist"]) for h in (1, 2)]
        else:
            if R[f"{name}_abd"] != 0.0:
                out.append((f"{name}_abd", R[f"{name}_abd"]))
            out += [(f"{name}_{seg}_{h}", R["flex"]) for seg in ("prox", "mid", "dist") for h in (1, 2)]
    return out


def _key(joint: str) -> str:
    """The SYNERGY / R key of a joint name."""
    if joint.endswith("_abd"):
        return joint
    if joint.startswith("thumb_prox") or joint.startswith("thumb_dist"):
        return joint[:10]
    return "flex"


def synergy_length(s: float) -> float:
    """Tendon length L_kin(s) = sum_j R_j clip(multiplier_j s) [rad] of the kinematic synergy at s."""
    total = 0.0
    for joint, r in tendon_entries():
        lo, hi = (0.0, PI / 2) if joint == "thumb_abd" else (-PI / 6, PI / 6) if joint.endswith("_abd") else FLEX_RANGE
        total += r * min(max(SYNERGY[_key(joint)] * s, lo), hi)
    return total


def transmission() -> tuple[float, float, float, float]:
    """(compliance C = sum R_j^2 / E_j [rad/(N·m)], gear g, kp, force limit of the actuator [N]).

    Position servo on the tendon: actuator force kp (u - g L), tendon force F = g kp (u - g L) = Kz (u / g - L)
    with Kz = kp g^2. In free space every unclipped joint settles at E_j q_j = R_j F, so q_j = multiplier_j s
    exactly when F = F1 s, i.e. when u = g (L_kin(s) + F1 s / Kz). The gear makes u = 1 the fully closed free
    hand (s = 1): g = 1 / (L_kin(1) + F1 / Kz).
    """
    C = sum(r * r / stiffness(_key(joint)) for joint, r in tendon_entries())
    g = 1.0 / (synergy_length(1.0) + F1 / MOTOR_STIFFNESS)
    kp = MOTOR_STIFFNESS / g**2
    return C, g, kp, FORCE_FACTOR * F1 / g


def command_for_synergy(s: float) -> float:
    """Motor command u in [0, 1] whose free-space equilibrium is the kinematic synergy at ``s``."""
    _, g, _, _ = transmission()
    return g * (synergy_length(s) + F1 * s / MOTOR_STIFFNESS)


def palm_frame_in_hand() -> tuple[np.ndarray, np.ndarray]:
    """Rotation (palm axes as columns, in the hand frame) and position [mm] of the palm frame in the bracket
    mount's hand frame.

    Palm +x (out of the palm) = hand +z; palm +y (toward the thumb) = hand -x; palm +z (along the fingers) =
    hand -y. The palm's back rests on the bracket's top; the palm box's centre lies over the flange axis.
    """
    Rm = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    centre = np.array([sum(PALM[0]) / 2, sum(PALM[1]) / 2, sum(PALM[2]) / 2])
    p = np.array([0.0, 0.0, BRACKET[2] + 1.0 - PALM[0][0]]) - Rm @ np.array([0.0, centre[1], centre[2]])
    return Rm, p


def palm_frame_inline() -> tuple[np.ndarray, np.ndarray]:
    """Rotation and position [mm] of the palm frame in the in-line mount's flange frame: palm axes = flange axes,
    the mounting base's axis (through the palm box's centre in x and y) on the tool axis, its end on the
    sensor's tool face."""
    pc = [(lo + hi) / 2 for lo, hi in PALM]
    return np.eye(3), np.array([-pc[0], -pc[1], SENSOR[1] + MOUNTING_BASE])


def grasp_frame_inline() -> tuple[np.ndarray, np.ndarray]:
    """Rotation and position [mm] of the grasp frame in the in-line mount's flange frame: the bracket mount's
    hand frame, posed so that the palm frame sits in it as on the bracket (T_FG = T_F,palm T_H,palm^-1)."""
    Rh, ph = palm_frame_in_hand()
    Rf, pf = palm_frame_inline()
    R = Rf @ Rh.T
    return R, pf - R @ ph


def rpy_of(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw [rad] of a rotation matrix (R = Rz(y) Ry(p) Rx(r)), away from pitch = ±pi/2."""
    return (math.atan2(R[2, 1], R[2, 2]), math.asin(-R[2, 0]), math.atan2(R[1, 0], R[0, 0]))


MODEL_NAMES = {"bracket": "pisa_iit_softhand_bracket", "inline": "pisa_iit_softhand"}


def mount_geom(mount: str) -> str:
    """The geom between the flange and the hand: the side bracket, or the F/T sensor on the tool axis."""
    if mount == "bracket":
        return (
            f'      <geom name="bracket_geom" type="box" size="{m(BRACKET[0] / 2, BRACKET[1] / 2, BRACKET[2] / 2)}"\n'
            f'            pos="{m(0, 0, BRACKET[2] / 2)}" mass="0.12" contype="{PALM_BIT}" conaffinity="1" '
            'rgba="0.6 0.6 0.62 1"/>'
        )
    return (
        f'      <geom name="sensor_geom" type="cylinder" size="{m(SENSOR[0] / 2, SENSOR[1] / 2)}"\n'
        f'            pos="{m(0, 0, SENSOR[1] / 2)}" mass="{SENSOR[2]:g}" contype="{PALM_BIT}" conaffinity="1" '
        'rgba="0.55 0.57 0.6 1"/>'
    )


def frame_comment(mount: str) -> str:
    """The MJCF header's lines on the hand frame."""
    if mount == "bracket":
        return (
            '  Hand frame = body "mount": origin at the robot flange, +z = out of the palm (the hand sits on a side '
            "bracket),\n  +x across the palm (thumb side to little-finger side), fingers along -y."
        )
    return (
        '  Flange frame = body "mount": origin at the robot flange, +z along the tool axis and the fingers (an ATI '
        "Gamma\n  sensor, then the hand's mounting base on the axis); the grasp frame (hand.toml) is +z out of the "
        "palm.\n "
    )


def build(mount: str = "inline") -> str:
    """The MJCF of the hand on ``mount`` ("bracket" | "inline")."""
    Rm, p = palm_frame_in_hand() if mount == "bracket" else palm_frame_inline()
    C, g, kp, frange = transmission()
    pc = [(lo + hi) / 2 for lo, hi in PALM]
    ph = [(hi - lo) / 2 for lo, hi in PALM]
    tendon = "\n".join(f'      <joint joint="{j}" coef="{c:g}"/>' for j, c in tendon_entries())
    equality = "\n".join(
        f'    <joint name="couple_{f}_{seg}" joint1="{f}_{seg}_2" joint2="{f}_{seg}_1" polycoef="0 1 0 0 0"/>'
        for f in FINGERS
        for seg in (("prox", "dist") if f == "thumb" else ("prox", "mid", "dist"))
    )
    fingers = "\n".join("        " + line for f in FINGERS for line in finger(f).splitlines())
    base_half = (MOUNTING_BASE - (-PALM[2][0])) / 2
    return f"""<!--
  Pisa/IIT SoftHand for softsig, generated by scripts/generate_softhand.py from the published description
  (README.md beside this file cites every number). Do not edit by hand: change the script and re-run it.
{frame_comment(mount)} Body "palm" is the published palm
  frame (+x out of the palm face, +y toward the thumb, +z along the fingers); the "wrist" site is its origin, the
  "knuckle" site the middle finger's abduction joint projected on the palm face (placement "knuckle").
  Units: m, rad, kg, N·m/rad. Control: "synergy" u in [0, 1], the motor position (0 open, 1 the fully closed
  free hand); u = g (L_kin(s) + F1 s / Kz) gives the kinematic synergy s exactly in free space (README).
  Free-space transmission: compliance sum R^2/E = {C:.6g} rad/(N·m), tendon force at s = 1: {F1:.6g} N·m.
-->
<mujoco model="{MODEL_NAMES[mount]}">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="implicitfast"/>

  <default>
    <default class="softhand">
      <geom friction="1.0 0.01 0.001" condim="4" solref="0.004 1" rgba="0.25 0.25 0.28 1"/>
      <site size="0.003" rgba="1 0.2 0.2 1"/>
      <default class="roll">
        <joint type="hinge" axis="0 -1 0" range="{FLEX_RANGE[0]:g} {FLEX_RANGE[1]:.8g}" springref="0"
               damping="{DAMPING:g}" armature="{ARMATURE:g}"/>
      </default>
      <default class="abd">
        <joint type="hinge" springref="0" damping="{DAMPING:g}" armature="{ARMATURE:g}"/>
      </default>
      <default class="link"><geom/></default>
      <default class="tip"><geom rgba="0.35 0.35 0.4 1"/></default>
    </default>
  </default>

  <worldbody>
    <body name="mount" childclass="softhand">
{mount_geom(mount)}
      <body name="palm" pos="{m(*p)}" quat="{quat(Rm)}">
        <site name="wrist" pos="0 0 0"/>
        <site name="knuckle" pos="{m(PALM[0][1], FINGERS["middle"][0][1], FINGERS["middle"][0][2])}"/>
        <geom name="palm_geom" type="box" size="{m(*ph)}" pos="{m(*pc)}" mass="{MASS["palm"]:g}"
              contype="{PALM_BIT}" conaffinity="1" rgba="0.2 0.2 0.22 1"/>
        <geom name="wrist_geom" type="cylinder" size="{m(ph[0], base_half)}"
              pos="{m(pc[0], pc[1], PALM[2][0] - base_half)}" mass="{BASE_MASS:g}" contype="{PALM_BIT}"
              conaffinity="1" rgba="0.6 0.6 0.62 1"/>
{fingers}
      </body>
    </body>
  </worldbody>

  <equality>
    <!-- rolling joints: the two hinges of each turn together 1:1 -->
{equality}
  </equality>

  <tendon>
    <!-- adaptive synergy: tendon length = sum R_j q_j (the description's R vector) -->
    <fixed name="synergy">
{tendon}
    </fixed>
  </tendon>

  <actuator>
    <!-- motor position loop on the synergy tendon: ctrl u in [0, 1];
         stiffness kp * gear^2 = {MOTOR_STIFFNESS:g} N·m/rad; largest tendon force {FORCE_FACTOR:g} x {F1:.4g} N·m -->
    <position name="synergy" tendon="synergy" kp="{kp:.8g}" gear="{g:.8g}" ctrlrange="0 1"
              forcerange="{-frange:.8g} {frange:.8g}"/>
  </actuator>
</mujoco>
"""


if __name__ == "__main__":
    C, g, kp, fr = transmission()
    for mount, name in MODEL_NAMES.items():
        out = HANDS / name / f"{name}.xml"
        out.write_text(build(mount))
        print(f"wrote {out}")
    print(f"C = {C:.4f} rad/(N·m), gear = {g:.6g}, kp = {kp:.6g}, force range = {fr:.6g}")
    R_FG, t_FG = grasp_frame_inline()
    print(f"in line: grasp_frame = {{ xyz = [{t_FG[0] / 1000:.6g}, {t_FG[1] / 1000:.6g}, {t_FG[2] / 1000:.6g}], "
          f"rpy = [{', '.join(f'{a!r}' for a in rpy_of(R_FG))}] }}")  # fmt: skip
    for s in (0.25, 0.5, 0.75, 1.0):
        print(f"s = {s}: u = {command_for_synergy(s):.6f}")
