import xml.etree.ElementTree as ET

import pybullet as p
import pytest

from vehicles.params import DEV_CHASSIS, SEDAN, VEHICLES
from vehicles.urdf import urdf_text, write_urdf


def test_urdf_is_deterministic_and_differs_per_vehicle():
    assert urdf_text(SEDAN) == urdf_text(SEDAN)
    assert urdf_text(SEDAN) != urdf_text(DEV_CHASSIS)


@pytest.mark.parametrize("params", list(VEHICLES.values()), ids=list(VEHICLES))
def test_urdf_structure_and_total_mass(params):
    robot = ET.fromstring(urdf_text(params))
    joints = {j.get("name"): j.get("type") for j in robot.iter("joint")}
    assert joints == {
        "steer_front_left": "revolute",
        "steer_front_right": "revolute",
        "spin_front_left": "continuous",
        "spin_front_right": "continuous",
        "spin_rear_left": "continuous",
        "spin_rear_right": "continuous",
    }
    masses = [float(m.get("value")) for m in robot.iter("mass")]
    assert sum(masses) == pytest.approx(params.mass, abs=1e-3)


def test_write_urdf_loads_in_pybullet(tmp_path):
    path = write_urdf(SEDAN, tmp_path)
    assert path == tmp_path / "sedan.urdf" and path.read_text() == urdf_text(SEDAN)
    assert write_urdf(SEDAN, tmp_path) == path
    cid = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(path), flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid)
        total = sum(p.getDynamicsInfo(body, link, physicsClientId=cid)[0] for link in range(-1, 6))
        assert p.getNumJoints(body, physicsClientId=cid) == 6
        assert total == pytest.approx(SEDAN.mass, abs=1e-3)
    finally:
        p.disconnect(cid)
