import math

import numpy as np
import pytest

from testbed.perception.detectors.labels import ego_lines
from tests.perception.conftest import ARC_R, LANE_W, pose_on
from tracks.map_api import OffMapError
from tracks.pose import Pose


@pytest.mark.parametrize(("lane", "offset", "yaw_deg"), [(0, 0.0, 0.0), (0, 0.4, 3.0), (1, -1.2, -5.0)])
def test_straight_road_gives_known_lines(track, lane, offset, yaw_deg):
    psi = math.radians(yaw_deg)
    truth = ego_lines(track, pose_on(track, lane, 30.0, offset, psi))
    assert truth.lane == lane
    assert truth.width == pytest.approx(LANE_W)
    assert truth.deviation == pytest.approx(offset, abs=1e-6)
    # a straight line at lateral offset d from the car, car yawed psi: y(x) = d / cos psi - x tan psi
    for coeffs, d in ((truth.left.coeffs, LANE_W / 2 - offset), (truth.right.coeffs, -LANE_W / 2 - offset)):
        np.testing.assert_allclose(coeffs, [d / math.cos(psi), -math.tan(psi), 0.0, 0.0], atol=2e-3)
    assert truth.left.exists and truth.right.exists
    assert truth.left.kind == ("dashed_white" if lane == 0 else "solid_yellow")


def test_arc_gives_curvature(track):
    truth = ego_lines(track, pose_on(track, 0, 215.0))
    c = truth.left.coeffs
    assert c[0] == pytest.approx(LANE_W / 2, abs=0.01)
    # y ≈ x² / (2 R') with R' the left line's radius (R - its offset)
    assert 2 * c[2] == pytest.approx(1.0 / (ARC_R - LANE_W / 2), rel=0.1)


def test_missing_lines(track):
    assert not ego_lines(track, pose_on(track, 0, 110.0)).right.exists  # unmarked stretch
    assert ego_lines(track, pose_on(track, 0, 110.0)).left.exists
    assert ego_lines(track, pose_on(track, 1, 110.0)).right.exists  # the lane line there is painted
    at_crossing = ego_lines(track, pose_on(track, 0, 398.0))
    assert not at_crossing.left.exists and not at_crossing.right.exists


def test_off_map_raises(track):
    with pytest.raises(OffMapError):
        ego_lines(track, Pose(30.0, 50.0, 0.0))
    with pytest.raises(OffMapError):
        ego_lines(track, Pose(math.nan, 0.0, 0.0))
