"""The Pisa/IIT SoftHand model against its published description (hands/pisa_iit_softhand/README.md).

The reference is built here, independently of the MJCF: a Pinocchio model assembled from the published table
(finger base positions and rpy in the palm frame, joint axes, 9 mm knuckle, rolling joints as hinge pairs 13 mm
apart and 9 mm between rolling joints, the thumb knuckle (22.5, -3.3, 0) mm rolled 0.42663 rad, fingertip pads
23 mm beyond the last hinge) and the description's kinematic synergy joint = multiplier * s.
"""

from __future__ import annotations

import copy
import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from softsig_service.config import Settings
from softsig_service.hands.closure import prepare_data
from softsig_service.hands.model import HandModel, load_hand

PI = math.pi
# published table (palm frame, mm; rpy rad), right hand
BASES = {
    "thumb": ((5.67, 29.62, 55.31), (0.0, -0.384, PI / 2)),
    "index": ((-3.3, 19.5, 93.70), (PI / 2, -1.4835, PI / 2)),
    "middle": ((-3.3, 0.0, 100.70), (PI, -PI / 2, 0.0)),
    "ring": ((-3.3, -19.5, 93.70), (-PI / 2, -1.5184, -PI / 2)),
    "little": ((-3.3, -39.0, 83.70), (-PI / 2, -1.4835, -PI / 2)),
}
# kinematic synergy multipliers [rad per unit s] and joint limits [rad]
ABDUCTION = {"thumb": 1.3 * PI / 2, "index": -0.2, "middle": 0.0, "ring": 0.2, "little": 0.4}
FLEX = PI / 4
THUMB_INNER = 1.3 * PI / 4
S_VALUES = (0.25, 0.5, 0.75, 1.0)
PALM_FACE_X = 0.0116  # [m] palm face, palm frame (the published palm collision shape)


def multiplier_and_limits(joint: str) -> tuple[float, float, float]:
    """(multiplier [rad], lower, upper [rad]) of a model joint by its name."""
    finger, rest = joint.split("_", 1)
    if rest == "abd":
        lo, hi = (0.0, PI / 2) if finger == "thumb" else (-PI / 6, PI / 6)
        return ABDUCTION[finger], lo, hi
    if finger == "thumb" and rest.startswith("prox"):
        return THUMB_INNER, 0.0, PI / 4
    return FLEX, 0.0, PI / 4


def synergy_q(joint: str, s: float) -> float:
    m, lo, hi = multiplier_and_limits(joint)
    return float(np.clip(m * s, lo, hi))


def reference_model() -> tuple[pin.Model, dict[str, int]]:
    """Pinocchio model of the published kinematics, palm frame = universe; joint names as the MJCF's."""
    model = pin.Model()
    tips: dict[str, int] = {}
    mm = 1e-3
    y_neg = np.array([0.0, -1.0, 0.0])
    for finger, (pos, rpy) in BASES.items():
        placement = pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(pos) * mm)
        axis = np.array([0.0, 0.0, -1.0 if finger == "thumb" else 1.0])
        parent = model.addJoint(0, pin.JointModelRevoluteUnaligned(axis), placement, f"{finger}_abd")
        if finger == "thumb":
            hinges = [
                (pin.SE3(pin.rpy.rpyToMatrix(0.42663, 0.0, 0.0), np.array([22.5, -3.3, 0.0]) * mm), "prox_1"),
                (pin.SE3(np.eye(3), np.array([13.0, 0, 0]) * mm), "prox_2"),
                (pin.SE3(np.eye(3), np.array([9.0, 0, 0]) * mm), "dist_1"),
                (pin.SE3(np.eye(3), np.array([13.0, 0, 0]) * mm), "dist_2"),
            ]
        else:
            hinges = []
            for k, seg in enumerate(("prox", "mid", "dist")):
                hinges.append((pin.SE3(np.eye(3), np.array([9.0, 0, 0]) * mm), f"{seg}_1"))
                hinges.append((pin.SE3(np.eye(3), np.array([13.0, 0, 0]) * mm), f"{seg}_2"))
                del k
        for placement, name in hinges:
            parent = model.addJoint(parent, pin.JointModelRevoluteUnaligned(y_neg), placement, f"{finger}_{name}")
        tips[finger] = model.addFrame(
            pin.Frame(
                f"{finger}_tip", parent, 0, pin.SE3(np.eye(3), np.array([23.0, 0, 0]) * mm), pin.FrameType.OP_FRAME
            )
        )
    return model, tips


def hinge_angles(hand: HandModel, data: mujoco.MjData) -> dict[str, float]:
    m = hand.model
    return {
        m.joint(j).name: float(data.qpos[m.jnt_qposadr[j]])
        for j in range(m.njnt)
        if int(m.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE)
    }


def command_for(hand: HandModel, s: float) -> float:
    """Motor command u whose free-space equilibrium is the synergy s, from the model's own transmission:
    tendon force F = Kz (u / g - L) with Kz = kp g^2, joints E_j q_j = R_j F; the synergy needs F = F1 s with
    F1 = E_flex * pi / 4, so u = g (L_kin(s) + F1 s / Kz), L_kin(s) = sum_j R_j q_j(s)."""
    m = hand.model
    act = hand.closure_actuators[0]
    g = float(m.actuator_gear[act, 0])
    kz = float(m.actuator_gainprm[act, 0]) * g * g
    tendon = int(m.actuator_trnid[act, 0])
    adr, num = int(m.tendon_adr[tendon]), int(m.tendon_num[tendon])
    length = 0.0
    for w in range(adr, adr + num):
        length += float(m.wrap_prm[w]) * synergy_q(m.joint(int(m.wrap_objid[w])).name, s)
    e_flex = float(m.jnt_stiffness[m.joint("middle_prox_1").id])
    return g * (length + e_flex * FLEX * s / kz)


def close_to(hand: HandModel, s: float, seconds: float = 2.0) -> mujoco.MjData:
    model = copy.copy(hand.model)
    model.opt.gravity[:] = 0
    data = prepare_data(hand, model)
    data.ctrl[list(hand.closure_actuators)] = command_for(hand, s)
    mujoco.mj_step(model, data, round(seconds / model.opt.timestep))
    return data


@pytest.fixture(scope="module")
def softhand(settings: Settings) -> HandModel:
    return load_hand("pisa_iit_softhand", settings)


@pytest.fixture(scope="module")
def closures(softhand: HandModel) -> dict[float, mujoco.MjData]:
    return {s: close_to(softhand, s) for s in S_VALUES}


def test_the_model_has_the_published_joint_layout(softhand: HandModel) -> None:
    names = set(hinge_angles(softhand, prepare_data(softhand, softhand.model)))
    assert len(names) == 33  # 4 fingers x (1 + 3 x 2) + thumb (1 + 2 x 2)
    assert softhand.model.neq == 14  # the second hinge of each rolling joint follows the first 1:1
    for j in names:
        _, lo, hi = multiplier_and_limits(j)
        assert tuple(softhand.model.jnt_range[softhand.model.joint(j).id]) == pytest.approx((lo, hi), abs=1e-6), j


@pytest.mark.parametrize("s", S_VALUES)
def test_free_closure_follows_the_published_kinematic_synergy(
    softhand: HandModel, closures: dict[float, mujoco.MjData], s: float
) -> None:
    angles = hinge_angles(softhand, closures[s])
    errors = {j: abs(q - synergy_q(j, s)) for j, q in angles.items()}
    worst = max(errors, key=lambda j: errors[j])
    assert math.degrees(errors[worst]) <= 3.0, (worst, math.degrees(angles[worst]), math.degrees(synergy_q(worst, s)))


@pytest.mark.parametrize("s", S_VALUES)
def test_fingertips_match_forward_kinematics_of_the_published_numbers(
    softhand: HandModel, closures: dict[float, mujoco.MjData], s: float
) -> None:
    ref, tips = reference_model()
    rdata = ref.createData()
    q = np.array([synergy_q(ref.names[j], s) for j in range(1, ref.njoints)])
    pin.framesForwardKinematics(ref, rdata, q)
    data = closures[s]
    palm = softhand.model.body("palm").id
    R, p = data.xmat[palm].reshape(3, 3), data.xpos[palm]
    for finger, fid in tips.items():
        sim = (data.site_xpos[softhand.model.site(f"{finger}_tip").id] - p) @ R  # in the palm frame
        assert np.linalg.norm(sim - rdata.oMf[fid].translation) <= 0.003, finger


def test_at_half_closure_the_thumb_meets_the_index_in_front_of_the_palm(
    softhand: HandModel, closures: dict[float, mujoco.MjData]
) -> None:
    data = closures[0.5]
    m = softhand.model
    thumb, index = (data.site_xpos[m.site(f"{f}_tip").id] for f in ("thumb", "index"))
    assert np.linalg.norm(thumb - index) <= 0.020
    palm = m.body("palm").id
    thumb_palm = (thumb - data.xpos[palm]) @ data.xmat[palm].reshape(3, 3)
    assert thumb_palm[0] > PALM_FACE_X + 0.02  # out of the palm, on the side the object is approached from
    # and in the hand frame that side is +z (the approach)
    mount = softhand.mount_body
    thumb_hand = (thumb - data.xpos[mount]) @ data.xmat[mount].reshape(3, 3)
    face_hand = (data.xpos[palm] + data.xmat[palm].reshape(3, 3) @ [PALM_FACE_X, 0, 0] - data.xpos[mount]) @ data.xmat[
        mount
    ].reshape(3, 3)
    assert thumb_hand[2] > face_hand[2] + 0.02


def test_the_wrist_reference_point_is_the_palm_frame_origin(softhand: HandModel) -> None:
    data = prepare_data(softhand, softhand.model)
    k = softhand.point_names.index("wrist")
    point = softhand.points[k]
    assert point.kind == "site"
    assert data.site_xpos[point.id] == pytest.approx(data.xpos[softhand.model.body("palm").id], abs=1e-9)


def test_the_grasp_frame_follows_the_convention(softhand: HandModel) -> None:
    """Grasp +z out of the palm (palm +x), grasp +x from the thumb side to the little finger (palm -y)."""
    data = prepare_data(softhand, softhand.model)
    R_palm = data.xmat[softhand.model.body("palm").id].reshape(3, 3)
    R_grasp = data.xmat[softhand.mount_body].reshape(3, 3) @ softhand.grasp_frame[:3, :3]
    palm_in_hand = R_grasp.T @ R_palm
    assert palm_in_hand[:, 0] == pytest.approx([0, 0, 1], abs=1e-9)
    assert palm_in_hand[:, 1] == pytest.approx([-1, 0, 0], abs=1e-9)
