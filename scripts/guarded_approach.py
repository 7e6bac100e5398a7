"""Guarded-approach diagnostic for the six nominal Table I cells (S, C x box, apple, cylinder; seed 1, no noise).

Same planner, same planned approach, closure, lift, hold and judge as softsig_service.simulation.rollout.simulate;
one phase is inserted between the planned approach and the closure:

  GUARDED DESCENT: the arm's joint targets keep moving along the approach direction (the unit vector from the
  pre-grasp to the grasp flange position, world frame) at a constant speed V [m/s], from the planned grasp pose
  (IK along the line, interpolated in joint space as the rollout does; position-servoed), until the summed normal
  contact force between hand geoms and object geoms (mujoco.mj_contactForce) exceeds F_c [N], or the descent has
  gone MAX_EXTRA [m] further than the plan. The target where it stopped is held during the closure; the lift is
  the 0.15 m straight line up from that stopped target pose (IK as arm_paths does).

Nothing in the package is edited: trial.arm_paths is wrapped (to know T_pre, T_grasp) and trial.simulate replaced
by guarded_simulate below. --fc none runs the unmodified rollout logic (baseline; no guarded phase).

Usage:  python scripts/guarded_approach.py --fc 2 5 10 [--speed 0.01] [--max-extra 0.03]
Writes one JSON line per (F_c, cell) to --out and prints a summary.
"""

from __future__ import annotations

import argparse
import json
import time

import mujoco
import numpy as np

import softsig_service.experiments.trial as trial
from softsig_service.hands.closure import closure_command
from softsig_service.objects import builtin_object
from softsig_service.simulation import rollout
from softsig_service.simulation.rollout import _interp, _quintic, line_ik
from softsig_service.simulation.scene_model import GEOM_HAND, GEOM_OBJECT, GEOM_TABLE, HAND_PREFIX

HALF_HEIGHT = {"box": 0.025, "apple": 0.036, "cylinder": 0.03}  # centre to top [m], resting pose

STATE: dict = {}  # set per trial: T_pre, T_grasp, fc, speed, max_extra, obj_name, record


# ---------------------------------------------------------------- contact read-outs
def contact_table(scene, data):
    """Per hand body: summed normal force [N] on the object; object-table normal force; hand z-force from the
    object [N] (world z, force on the hand); list of touching hand bodies."""
    m = scene.model
    cls = scene.geom_class
    f6 = np.zeros(6)
    per_body: dict[str, float] = {}
    table_n = 0.0
    hand_obj_n = 0.0
    hand_fz = 0.0  # force of the object on the hand along world z
    hand_table_fz = 0.0  # force of the table on the hand along world z
    for i in range(data.ncon):
        c = data.contact[i]
        if c.dist > 0.0:
            continue
        g1, g2 = int(c.geom[0]), int(c.geom[1])
        k1, k2 = cls[g1], cls[g2]
        mujoco.mj_contactForce(m, data, i, f6)
        fn = float(f6[0])
        if {k1, k2} == {GEOM_HAND, GEOM_OBJECT}:
            hg = g1 if k1 == GEOM_HAND else g2
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[hg])) or str(hg)
            name = name.removeprefix(HAND_PREFIX)
            per_body[name] = per_body.get(name, 0.0) + fn
            hand_obj_n += fn
            # mj_contactForce: force in the contact frame, exerted by geom1 on geom2 (normal from geom1 to geom2)
            fw = c.frame.reshape(3, 3).T @ f6[:3]
            hand_fz += float(fw[2]) if hg == g2 else -float(fw[2])
        elif {k1, k2} == {GEOM_OBJECT, GEOM_TABLE}:
            table_n += fn
        elif {k1, k2} == {GEOM_HAND, GEOM_TABLE}:
            hg = g1 if k1 == GEOM_HAND else g2
            fw = c.frame.reshape(3, 3).T @ f6[:3]
            hand_table_fz += float(fw[2]) if hg == g2 else -float(fw[2])
    return {
        "hand_object_normal": hand_obj_n,
        "hand_fz_from_object": hand_fz,
        "object_table_normal": table_n,
        "hand_fz_from_table": hand_table_fz,
        # what a wrist F/T sensor's z would see from contacts (upward push on the hand), object + table
        "wrist_fz_contacts": hand_fz + hand_table_fz,
        "per_body": {k: round(v, 2) for k, v in sorted(per_body.items(), key=lambda kv: -kv[1])},
    }


def geometry(scene, data, obj_name):
    """Palm height above the object's top (palm_geom's lowest face centre vs centre z + half height), signed
    distance palm_geom-object (mj_geomDistance), flange z, object centre in the hand frame [m]."""
    m = scene.model
    pid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, HAND_PREFIX + "palm_geom")
    R = data.geom_xmat[pid].reshape(3, 3)
    size = m.geom_size[pid]
    # face whose outward normal points most along world -z
    best = None
    for ax in range(3):
        for sgn in (-1.0, 1.0):
            n = sgn * R[:, ax]
            if best is None or n[2] < best[0]:
                best = (n[2], data.geom_xpos[pid] + n * size[ax])
    palm_face_z = float(best[1][2])
    top = float(scene.object_position(data)[2]) + HALF_HEIGHT[obj_name]
    fromto = np.zeros(6)
    dists = [mujoco.mj_geomDistance(m, data, pid, int(g), 0.1, fromto) for g in scene.object_geoms]
    # thumb distal link distance too
    tid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, HAND_PREFIX + "thumb_dist_geom")
    tdist = [mujoco.mj_geomDistance(m, data, tid, int(g), 0.1, fromto) for g in scene.object_geoms]
    return {
        "palm_face_above_top": palm_face_z - top,
        "palm_geom_distance": float(min(dists)),
        "thumb_dist_distance": float(min(tdist)),
        "flange_z": float(data.xpos[scene.flange_body][2]),
        "object_in_hand": [round(float(v), 4) for v in scene.object_in_flange(data)],
        "object_z": float(scene.object_position(data)[2]),
    }


def snapshot(scene, data, obj_name, label):
    d = {"t": float(data.time)}
    d.update(geometry(scene, data, obj_name))
    d.update(contact_table(scene, data))
    STATE["record"][label] = d


# ---------------------------------------------------------------- wrapped package functions
_orig_arm_paths = trial.arm_paths


def arm_paths_spy(ur5, T_pre, T_grasp, q_pre, cfg):
    STATE["T_pre"] = np.array(T_pre, dtype=float)
    STATE["T_grasp"] = np.array(T_grasp, dtype=float)
    STATE["ur5"] = ur5
    return _orig_arm_paths(ur5, T_pre, T_grasp, q_pre, cfg)


def guarded_simulate(scene, obj, approach, lift, cfg, on_frame, frame_period):
    """rollout.simulate with a guarded descent between the approach and the closure (module docstring)."""
    run = rollout.Run(scene, obj, approach[0], cfg)
    data, out, tick = run.data, run.out, run.tick
    closure = scene.hand.manifest.closure
    arm_act, clo_act = scene.arm_actuators, scene.closure_actuators
    c_open, c_closed = scene.closure_open, scene.closure_closed
    rec = STATE["record"]
    name = STATE["obj_name"]

    def trace() -> None:
        if STATE.get("trace"):
            ct = contact_table(scene, data)
            STATE["record"].setdefault("trace", []).append(
                {
                    "t": round(float(data.time), 3),
                    "rise": round(float(scene.object_position(data)[2]) - run.z0, 4),
                    "flange_z": round(float(data.xpos[scene.flange_body][2]), 4),
                    "obj_in_hand": [round(float(v), 4) for v in scene.object_in_flange(data)],
                    "Fn": round(ct["hand_object_normal"], 1),
                    "Fz": round(ct["hand_fz_from_object"], 1),
                    "Ftab": round(ct["object_table_normal"], 1),
                    "bodies": ct["per_body"],
                }
            )

    def step_and_check(grasping: bool) -> bool:
        if not run.step(grasping):
            return False
        trace()
        return True

    def phase(duration, arm, hand, grasping) -> bool:
        return run.phase(duration, arm, hand, grasping, trace)

    q_grasp = approach[-1]

    def open_hand(_t):
        return c_open

    def closed_hand(_t):
        return c_closed

    def ramp(t):
        return closure_command(scene.hand, t, closure.duration)

    ok = phase(cfg.approach_time, lambda t: _interp(approach, _quintic(t / cfg.approach_time)), open_hand, False)
    if ok:
        snapshot(scene, data, name, "end_of_planned_approach")

    fc = STATE["fc"]
    q_hold = q_grasp
    extra = 0.0
    reached = None
    if ok and fc is not None:
        ur5 = STATE["ur5"]
        T_pre, T_grasp = STATE["T_pre"], STATE["T_grasp"]
        d = T_grasp[:3, 3] - T_pre[:3, 3]
        d /= np.linalg.norm(d)
        max_extra, v = STATE["max_extra"], STATE["speed"]
        T_end = T_grasp.copy()
        T_end[:3, 3] += max_extra * d
        n_wp = round(max_extra / 0.0005) + 1  # a waypoint every 0.5 mm
        gpath = line_ik(ur5, T_grasp, T_end, q_grasp, n_wp)
        if gpath is None:
            rec["guarded_error"] = "unreachable:guarded"
        else:
            # the first check: already above the threshold at the end of the planned approach?
            sig = STATE["signal"]
            f = contact_table(scene, data)[sig]
            k = 0
            while f <= fc:
                k += 1
                extra = min(v * k * tick, max_extra)
                q_hold = _interp(gpath, extra / max_extra)
                data.ctrl[arm_act] = q_hold
                data.ctrl[clo_act] = c_open
                if not step_and_check(False):
                    ok = False
                    break
                f = contact_table(scene, data)[sig]
                if extra >= max_extra:
                    break
            reached = bool(ok and f > fc)
            T_stop = T_grasp.copy()
            T_stop[:3, 3] += extra * d
            T_top = T_stop.copy()
            T_top[2, 3] += cfg.lift
            lift2 = line_ik(ur5, T_stop, T_top, q_hold, cfg.waypoints)
            if lift2 is None:
                rec["guarded_error"] = "unreachable:lift"
                ok = False
            else:
                lift = lift2
    rec["guarded"] = {
        "fc": fc,
        "extra_descent": extra,
        "threshold_reached": reached,
        "guard_time": float(data.time) - cfg.approach_time,
    }
    if ok:
        snapshot(scene, data, name, "closure_start")

    q_top = lift[-1]
    ok = ok and phase(closure.duration + closure.settle, lambda _t: q_hold, ramp, False)
    if ok:
        out.touching_after_close = scene.contact_summary(data).object_hand
        snapshot(scene, data, name, "end_of_closure")
    ok = ok and phase(cfg.lift_time, lambda t: _interp(lift, _quintic(t / cfg.lift_time)), closed_hand, True)
    if ok:
        snapshot(scene, data, name, "end_of_lift")
    p_hold = scene.object_in_flange(data)
    ok = ok and (cfg.hold_time <= 0.0 or phase(cfg.hold_time, lambda _t: q_top, closed_hand, True))
    if ok:
        snapshot(scene, data, name, "end_of_hold")
    return run.finish(ok, p_hold)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hand", default="pisa_iit_softhand")
    ap.add_argument("--fc", nargs="+", default=["2", "5", "10"], help="thresholds [N]; 'none' = baseline")
    ap.add_argument("--speed", type=float, default=0.01, help="guarded descent speed [m/s]")
    ap.add_argument("--max-extra", type=float, default=0.03, help="max descent beyond the plan [m]")
    ap.add_argument("--cells", nargs="*", default=None, help="e.g. S:box C:apple (default all six)")
    ap.add_argument(
        "--signal",
        default="hand_object_normal",
        choices=["hand_object_normal", "wrist_fz_contacts"],
        help="guard signal: summed hand-object normal force, or the world-z contact force on the hand",
    )
    ap.add_argument("--trace", action="store_true", help="record every control tick (large output)")
    ap.add_argument("--out", default="guarded_approach.jsonl", help="JSON lines to append to")
    args = ap.parse_args()
    STATE["trace"] = args.trace
    STATE["signal"] = args.signal
    trial.arm_paths = arm_paths_spy
    trial.simulate = guarded_simulate
    planner = trial.default_planner()
    cells = args.cells or [f"{s}:{o}" for s in ("S", "C") for o in ("box", "apple", "cylinder")]
    with open(args.out, "a") as fh:
        for fc_text in args.fc:
            fc = None if fc_text == "none" else float(fc_text)
            line = []
            for cell in cells:
                strategy, oname = cell.split(":")
                STATE.update(fc=fc, speed=args.speed, max_extra=args.max_extra, obj_name=oname, record={})
                t0 = time.perf_counter()
                r = trial.run_trial(args.hand, builtin_object(oname), strategy, seed=1, planner=planner)
                rec = {
                    "fc": fc,
                    "signal": args.signal,
                    "speed": args.speed,
                    "max_extra": args.max_extra,
                    "strategy": strategy,
                    "object": oname,
                    "success": r.success,
                    "reason": r.reason,
                    "rise": r.lift_height,
                    "max_rise": r.max_lift,
                    "wall": time.perf_counter() - t0,
                    **STATE["record"],
                }
                fh.write(json.dumps(rec) + "\n")
                fh.flush()
                g = STATE["record"].get("guarded", {})
                cs = STATE["record"].get("closure_start", {})
                print(
                    f"Fc={fc_text:>4} {strategy}:{oname:<8} {'OK' if r.success else r.reason:<10} "
                    f"rise={r.lift_height:+.3f} max={r.max_lift:+.3f} extra={1000 * g.get('extra_descent', 0):.1f}mm "
                    f"reached={g.get('threshold_reached')} palm_above_top={1000 * cs.get('palm_face_above_top', float('nan')):.1f}mm "
                    f"wall={time.perf_counter() - t0:.0f}s",
                    flush=True,
                )
                line.append(f"{strategy}:{oname}={'OK' if r.success else r.reason}({r.lift_height:+.3f})")
            print(f"== Fc={fc_text}: " + " ".join(line), flush=True)


if __name__ == "__main__":
    main()
