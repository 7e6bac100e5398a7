"""The built-in hand models: they compile, step cleanly, close, converge and adapt to obstacles."""

from __future__ import annotations

import copy
import dataclasses

import mujoco
import numpy as np
import pytest

from softsig_service.config import Settings
from softsig_service.geometry.transforms import axis_angle_to_matrix
from softsig_service.hands.closure import prepare_data, run_closure, simulate_closure
from softsig_service.hands.manifest import load_manifest
from softsig_service.hands.model import HandModel, builtin_hand_names, compile_hand, load_hand
from softsig_service.hands.summary import fingertip_spread
from softsig_service.signatures.closure import compute_closure_signature

BUILTIN_HANDS = builtin_hand_names()
EXPECTED_HANDS = {"pisa_iit_softhand", "sdm_hand", "rbo_hand2", "parallel_gripper"}
CONVERGENCE_RATIO = 0.7
"""Closure converges when the fingertips' mean distance to their centroid shrinks to <= 70 % of the open one."""


def test_all_four_hands_ship() -> None:
    assert set(BUILTIN_HANDS) >= EXPECTED_HANDS


@pytest.mark.parametrize("name", BUILTIN_HANDS)
def test_scene_compiles_and_steps_one_second_without_warnings(name: str, settings: Settings) -> None:
    hand = load_hand(name, settings)
    assert hand.manifest.scene is not None
    model = mujoco.MjModel.from_xml_path(str(hand.folder / hand.manifest.scene))
    assert model.opt.gravity[2] < 0  # the scene keeps gravity on
    data = mujoco.MjData(model)
    for _ in range(round(1.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    assert [w.number for w in data.warning] == [0] * len(data.warning)
    assert np.all(np.isfinite(data.qpos))


@pytest.mark.parametrize("name", BUILTIN_HANDS)
def test_closure_makes_fingertips_converge(name: str, settings: Settings) -> None:
    hand = load_hand(name, settings)
    traj = simulate_closure(hand, surface_points=0)
    open_spread = fingertip_spread(traj.positions[0], traj.point_names)
    closed_spread = fingertip_spread(traj.positions[-1], traj.point_names)
    assert closed_spread <= CONVERGENCE_RATIO * open_spread, (open_spread, closed_spread)
    assert traj.frame_id == "hand"
    assert traj.times[0] == 0.0
    assert traj.n_points >= 4 and "wrist" in traj.point_names


@pytest.mark.parametrize("name", BUILTIN_HANDS)
def test_hand_frame_conventions(name: str, settings: Settings) -> None:
    """The hand lies on the approach side (+z) of the flange at the origin; the wrist point stays put."""
    hand = load_hand(name, settings)
    assert np.allclose(hand.model.body_pos[hand.mount_body], 0) and np.allclose(
        hand.model.body_quat[hand.mount_body], [1, 0, 0, 0]
    )
    traj = simulate_closure(hand, surface_points=0)
    tips = [k for k, n in enumerate(traj.point_names) if n.endswith("_tip")]
    wrist = traj.point_names.index("wrist")
    assert np.all(traj.positions[:, tips, 2] > 0.0)
    np.testing.assert_allclose(traj.positions[:, wrist], np.broadcast_to(traj.positions[0, wrist], (traj.n_frames, 3)))


def test_closure_is_deterministic_and_leaves_cached_model_untouched(settings: Settings) -> None:
    hand = load_hand("pisa_iit_softhand", settings)
    gravity = hand.model.opt.gravity.copy()
    a = simulate_closure(hand)
    b = simulate_closure(hand)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.surface is not None and b.surface is not None
    np.testing.assert_array_equal(a.surface, b.surface)
    np.testing.assert_array_equal(hand.model.opt.gravity, gravity)


def test_surface_points_are_on_the_hand_and_move_with_it(settings: Settings) -> None:
    hand = load_hand("pisa_iit_softhand", settings)
    traj = simulate_closure(hand, surface_points=800)
    assert traj.surface is not None
    assert 600 <= traj.surface.shape[1] <= 1600  # ~800 requested; every one of the 50+ geoms gets a few
    moved = np.linalg.norm(traj.surface[-1] - traj.surface[0], axis=1)
    assert moved.max() > 0.05  # fingertip surfaces travel several centimetres
    assert np.mean(moved > 0.005) > 0.15  # the fingers move (bracket, palm and wrist, most of the area, stay)


def test_gravity_option_changes_the_closure(settings: Settings) -> None:
    hand = load_hand("sdm_hand", settings)
    free = simulate_closure(hand, surface_points=0, gravity=False)
    heavy = simulate_closure(hand, surface_points=0, gravity=True)
    assert not np.allclose(free.positions, heavy.positions)


# --- adaptivity: one finger blocked at its proximal link ---------------------------------------------------

ADAPTIVE_CASES = {
    # hand: (proximal body, a point on its link axis and the flexion direction, both in the body frame [m],
    #        index of the geom size that is its half-thickness, proximal joint, distal joint, other fingers)
    "pisa_iit_softhand": (
        "index_prox_roll",
        (0.006, 0.0, 0.0),
        (0.0, 0.0, 1.0),
        2,
        "index_prox_1",
        "index_dist_1",
        ("middle", "ring", "little"),
    ),
    "sdm_hand": ("f1_proximal", (0.0, 0.0, 0.03), (0.0, 1.0, 0.0), 0, "f1_proximal", "f1_distal", ("f2", "f3", "f4")),
}


def _joint_angles(model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, float]:
    return {
        model.joint(j).name: float(data.qpos[model.jnt_qposadr[j]])
        for j in range(model.njnt)
        if int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    }


def _close(hand: HandModel) -> dict[str, float]:
    model = copy.copy(hand.model)
    model.opt.gravity[:] = 0
    data = prepare_data(hand, model)
    closure = hand.manifest.closure
    run_closure(hand, model, data, duration=closure.duration, settle=closure.settle)
    return _joint_angles(model, data)


@pytest.mark.parametrize("name", sorted(ADAPTIVE_CASES))
def test_blocked_finger_keeps_wrapping_and_others_close_as_in_free_space(name: str, settings: Settings) -> None:
    prox_body, along, flexion, size_index, prox_joint, dist_joint, others = ADAPTIVE_CASES[name]
    free_hand = load_hand(name, settings)
    free = _close(free_hand)

    # the proximal link's position and closing direction in the open hand (hand frame = world here)
    model = free_hand.model
    data = prepare_data(free_hand, copy.copy(model))
    body = model.body(prox_body).id
    radius = float(model.geom_size[model.body_geomadr[body], size_index])
    centre = data.xpos[body] + data.xmat[body].reshape(3, 3) @ np.array(along)
    towards = data.xmat[body].reshape(3, 3) @ np.array(flexion)  # the direction the link flexes toward

    def add_obstacle(spec: mujoco.MjSpec) -> None:
        spec.worldbody.add_geom(
            name="obstacle",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[0.004, 0.003, 0.004],
            pos=centre + towards * (radius + 0.0045),
        )

    manifest_path = free_hand.folder / "hand.toml"
    blocked_hand = compile_hand(load_manifest(manifest_path), free_hand.folder, settings.limits, add_obstacle)
    blocked = _close(blocked_hand)

    assert blocked[prox_joint] < 0.35 * free[prox_joint], "the obstacle must stop the proximal link"
    assert blocked[dist_joint] > 0.7 * free[dist_joint], "the distal joints keep closing around the obstacle"
    for other in others:
        for joint, angle in free.items():
            if not joint.startswith(other + "_"):
                continue
            if joint.endswith("_abd"):
                # the tendon length the blocked finger does not take goes partly into the abductions, the only
                # joints of a closed free hand short of their limits: they turn at least as far as in free space
                assert blocked[joint] * np.sign(angle) >= abs(angle) - 0.01, joint
            else:
                assert blocked[joint] == pytest.approx(angle, abs=0.08), joint


@pytest.mark.parametrize("name", BUILTIN_HANDS)
def test_closure_signature_axis_keeps_its_sign_under_a_tiny_rotation(name: str, settings: Settings) -> None:
    """Every built-in hand's CS axes lie near a coordinate plane (x ~ 0); rotating the closure by 1e-7 rad must
    not flip them (the rotated axis is the rotated original, sign included)."""
    traj = simulate_closure(load_hand(name, settings), surface_points=0)
    for method in ("ellipsoid", "pca"):
        cs = compute_closure_signature(traj, method)  # type: ignore[arg-type]
        for axis in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.6, 0.0, 0.8)):
            for angle in (1e-7, -1e-7):
                R = axis_angle_to_matrix(axis, angle)
                turned = dataclasses.replace(traj, positions=traj.positions @ R.T)
                cs_r = compute_closure_signature(turned, method)  # type: ignore[arg-type]
                assert float(cs_r.axis @ (R @ cs.axis)) > 1.0 - 1e-6, (method, axis, angle, cs.axis, cs_r.axis)
