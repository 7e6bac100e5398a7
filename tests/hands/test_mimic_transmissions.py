"""mimic_couplings reads the robot's joints only: a transmission's joint elements of the same names (as in the
official Pisa/IIT SoftHand description) do not hide the real joints' mimic tags."""

from __future__ import annotations

from softsig_service.hands.mimic import mimic_couplings

URDF = """<robot name="r">
  <link name="a"/><link name="b"/><link name="c"/>
  <joint name="synergy" type="revolute"><parent link="a"/><child link="b"/>
    <axis xyz="0 0 1"/><limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="finger" type="revolute"><parent link="b"/><child link="c"/>
    <axis xyz="0 0 1"/><limit lower="0" upper="1" effort="1" velocity="1"/>
    <mimic joint="synergy" multiplier="0.75" offset="0.1"/></joint>
  <transmission name="t_finger"><type>transmission_interface/SimpleTransmission</type>
    <joint name="finger"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
    <actuator name="m"><mechanicalReduction>1</mechanicalReduction></actuator></transmission>
  <transmission name="t_synergy"><type>transmission_interface/SimpleTransmission</type>
    <joint name="synergy"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
    <actuator name="s"><mechanicalReduction>1</mechanicalReduction></actuator></transmission>
</robot>"""


def test_transmission_joint_elements_do_not_replace_the_robots_joints() -> None:
    couplings = mimic_couplings(URDF)
    assert set(couplings) == {"finger"}
    c = couplings["finger"]
    assert c.root == "synergy" and c.multiplier == 0.75 and c.offset == 0.1
