import math

import numpy as np
import pytest

from testbed.perception.training.occlusion import hidden, occluded_fraction
from tests.perception.conftest import pose_on
from tracks.pose import Pose
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

SEDAN = get_vehicle("sedan")
SIZE = (SEDAN.length, SEDAN.width, SEDAN.height)


def test_a_box_hides_the_ground_behind_it_not_beside_or_before_it():
    camera = np.array([0.5, 0.0, 1.4])
    car = Pose(10.0, 0.0, 0.0)  # rear face at x = 7.55, half width 0.95
    points = np.array([[20.0, 0.0, 0.0], [12.0, 1.75, 0.0], [30.0, 1.75, 0.0], [5.0, 0.0, 0.0], [10.0, 0.5, 0.0],
                       [20.0, -4.0, 0.0]])
    assert hidden(camera, points, car, SIZE).tolist() == [True, False, True, False, True, False]
    turned = Pose(10.0, 0.0, math.pi / 2)  # across the lane: 4.9 m wide, 1.9 m deep
    assert hidden(camera, np.array([[20.0, 1.75, 0.0]]), turned, SIZE).tolist() == [True]


def test_a_lead_car_hides_the_far_lines_only_when_close(track):
    rig = CameraRig(SEDAN.camera)
    pose = pose_on(track, 0, 50.0)
    shares = {}
    for ahead in (4.0, 8.0, 15.0):
        centre = 50.0 + 0.5 * SEDAN.length + ahead + 0.5 * SEDAN.length
        shares[ahead] = occluded_fraction(track, pose, rig, [pose_on(track, 0, centre)], SIZE)
    # straight 3.5 m lane: a line at y = 1.75 is hidden from x = mount_x + d · 1.75 / 0.95 on (d: camera to rear)
    first_hidden = [rig.mount_x + (0.5 * SEDAN.length + a - rig.mount_x) * 1.75 / 0.95 for a in (4.0, 8.0)]
    expected = [len([x for x in range(5, 31) if x > h]) / 26 for h in first_hidden]
    assert [shares[4.0], shares[8.0]] == pytest.approx(expected)
    assert shares[15.0] == 0.0
    assert occluded_fraction(track, pose, rig, [], SIZE) == 0.0
    assert occluded_fraction(track, pose, rig, [pose_on(track, 1, 60.0)], SIZE) == 0.0  # beside, next lane
    assert occluded_fraction(track, Pose(0.0, 500.0, 0.0), rig, [], SIZE) is None  # off the road
