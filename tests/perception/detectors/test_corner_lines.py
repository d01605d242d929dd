"""The map's lane lines on a town corner (radius 7 m, turning across the car's path within the 40 m range): the
fitted cubic keeps the lines' offset and slope at x = 0 and is fitted over the range where it follows them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from testbed.lane_detection import CameraFrame
from testbed.perception.detectors.labels import X_MAX, ego_lines
from testbed.perception.detectors.oracle import OracleLaneDetector
from tracks.geometry import Arc, ReferenceLine, Straight
from tracks.layout import Edge
from tracks.pose import Pose
from tracks.road import Track


def _corner() -> Track:
    reference = ReferenceLine(Pose(0.0, 0.0, 0.0), [Straight(60.0), Arc(7.0, 7.0 * math.pi / 2), Straight(60.0)])
    return Track("corner", 0, "a 90° town corner", reference, [3.5], ["solid_white", "solid_white"],
                 Edge("shoulder", 1.0, "grass"), Edge("shoulder", 1.0, "grass"))


@pytest.mark.parametrize("before", [30.0, 15.0, 6.0, 1.0])
def test_lines_before_a_tight_corner_keep_their_offset_and_slope_at_the_car(before):
    track = _corner()
    lane = track.lanes[0]
    s = 60.0 - before
    x, y = lane.position(s, 0.2)  # 0.2 m left of the centre, 0.03 rad to the left of the lane
    pose = Pose(float(x), float(y), lane.heading_at(s) + 0.03)
    truth = ego_lines(track, pose)
    for line, side in ((truth.left, 1.0), (truth.right, -1.0)):
        # the car is 0.2 m left and turned 0.03 rad left: a line at ±1.75 m lies at ±1.75 − 0.2 (cos 0.03 apart)
        assert line.coeffs[0] == pytest.approx((side * 1.75 - 0.2) / math.cos(0.03), abs=0.002)
        assert -math.atan(line.coeffs[1]) == pytest.approx(0.03, abs=0.002)
    if before < 30.0:  # the corner lies within the range: the fit is shortened
        assert min(truth.left.x_far, truth.right.x_far) < X_MAX
    detection = OracleLaneDetector(track, np.random.default_rng(0)).detect(CameraFrame(0.0, None, pose))
    assert detection.x_range == (0.0, min(truth.left.x_far, truth.right.x_far))


def test_a_straight_road_is_fitted_over_the_whole_range():
    track = _corner()
    truth = ego_lines(track, Pose(5.0, 0.1, 0.0))
    assert truth.left.x_far == X_MAX and truth.right.x_far == X_MAX
    assert truth.left.coeffs == pytest.approx([1.65, 0.0, 0.0, 0.0], abs=1e-6)


def _circle_offset(radius: float, x: np.ndarray) -> np.ndarray:
    """Offset y(x) of a circle of `radius` curving left, tangent to the x axis at the origin."""
    return radius - np.sqrt(radius**2 - x**2)


def test_the_lines_offsets_ahead_follow_the_corner_where_the_cubic_does_not():
    track = _corner()
    lane = track.lanes[0]
    x, y = lane.position(60.0, 0.0)
    pose = Pose(float(x), float(y), lane.heading_at(60.0))  # at the corner's start, centred, along the lane
    truth = ego_lines(track, pose)
    xs = np.array([1.0, 3.0, 5.0, 6.0, 8.0, 12.0, 20.0])
    for line, radius in ((truth.left, 7.0 - 1.75), (truth.right, 7.0 + 1.75)):
        ahead = xs[xs < radius - 0.5]  # the line runs away from the car until it has turned 90°
        expected = _circle_offset(radius, ahead) + (1.75 if radius < 7.0 else -1.75)
        np.testing.assert_allclose(line.offsets_at(ahead), expected, atol=0.01)
        assert np.isnan(line.offsets_at(xs[xs > radius + 0.5])).all()  # past the turn: no offset
    inner = np.array([3.5, 4.0, 4.5])  # the inner line in the turn, which the cubic cannot follow (range ≥ 8 m)
    cubic = np.polynomial.polynomial.polyval(inner, truth.left.coeffs)
    assert np.abs(cubic - truth.left.offsets_at(inner)).max() > 0.25
