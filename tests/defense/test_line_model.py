"""Where a detection's lines are evidence: not where the lane turns on a town corner's radius within their near
range; LD3 (fail-closed) withholds them there without losing the check of the MSF pose."""

import math

import numpy as np
import pytest

from testbed.defense.config import PAPER_MODE, DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.line_model import NEAR_RANGE, followable, tight_turn
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.geometry import Arc, ReferenceLine, Straight
from tracks.layout import Edge
from tracks.pose import Pose
from tracks.road import Track
from tracks.semantic_map import TrackMap

WIDTH = 3.5
CORNER_AT = 100.0  # m of straight before a 90° left corner of radius 11 m


def _map(*segments) -> TrackMap:
    edge = Edge("shoulder", paved=1.0, ground="grass")
    ref = ReferenceLine(Pose(0.0, 0.0, 0.0), list(segments))
    return TrackMap(Track("t", 0, "t", ref, [WIDTH, WIDTH], ["solid_white", "dashed_white", "solid_white"], edge,
                          edge, ego_lane=0))


@pytest.fixture(scope="module")
def corner() -> TrackMap:
    return _map(Straight(CORNER_AT), Arc(11.0, 11.0 * math.pi / 2), Straight(100.0))


def _on_lane(x: float) -> Pose:
    return Pose(x, 0.0, 0.0)  # the reference line is the ego lane's centre


def _lines(t: float, c0_left: float, c0_right: float) -> LaneDetection:
    return LaneDetection(t, np.array([c0_left, 0.0, 0.0, 0.0]), np.array([c0_right, 0.0, 0.0, 0.0]), 1.0, 1.0,
                         (0.0, 30.0))


def test_a_tight_turn_is_found_within_the_near_range_only(corner):
    assert tight_turn(corner, _on_lane(40.0), 0, 20.0) is None  # 60 m before the corner
    assert tight_turn(corner, _on_lane(CORNER_AT - NEAR_RANGE - 2.0), 0, 20.0) is None
    assert tight_turn(corner, _on_lane(CORNER_AT - NEAR_RANGE + 2.0), 0, 20.0) == pytest.approx(11.0, rel=0.01)
    assert tight_turn(corner, _on_lane(CORNER_AT - 5.0), 0, 10.0) is None  # under the radius asked for only
    wide = _map(Straight(50.0), Arc(60.0, 150.0))
    assert tight_turn(wide, _on_lane(60.0), 0, 20.0) is None
    assert tight_turn(_map(Straight(60.0)), _on_lane(55.0), 0, 20.0) is None  # the map ends: nothing to judge


def test_the_lines_are_withheld_on_the_corner_and_kept_elsewhere(corner):
    ld = _lines(0.0, WIDTH / 2, -WIDTH / 2)
    assert followable(ld, corner, _on_lane(40.0), 0, 20.0) == (ld, None)
    kept, turn = followable(ld, corner, _on_lane(CORNER_AT - 5.0), 0, 20.0)
    assert kept.left is None and kept.right is None and kept.left_prob == kept.right_prob == 0.0
    assert turn == pytest.approx(11.0, rel=0.01)


def _drive(defense: Ld3Defense, smap: TrackMap, until: float, msf_offset: float, lines_offset: float) -> None:
    """A car centred on the lane at 10 m/s along the straight; odometry at 40 Hz, detections at 20 Hz. Once the
    corner is within 10 m the MSF pose is `msf_offset` left of the car and the lines read the car `lines_offset`
    left of where it is (a detector's extrapolation error)."""
    dt, speed = 0.025, 10.0
    for k in range(int(until / dt) + 1):
        t = k * dt
        defense.on_odometry(t, speed, 0.0)
        if k % 2:
            continue
        x = 5.0 + speed * t
        near = CORNER_AT - x < 10.0
        err = lines_offset if near else 0.0
        ld = _lines(t, WIDTH / 2 - err, -WIDTH / 2 - err)
        est = LocalizationEstimate(t, Pose(x, msf_offset if near else 0.0, 0.0), np.eye(3) * 0.01)
        defense.on_lane_detection(ld, est, smap)


def test_fail_closed_ld3_withholds_the_lines_on_a_corner_and_checks_the_msf_by_odometry(corner):
    benign = Ld3Defense(DefenseConfig())
    _drive(benign, corner, 9.4, msf_offset=0.0, lines_offset=1.0)
    assert benign.detection_time is None
    assert benign.faults.counts["corner-lines"] > 0 and benign.faults.counts["no-lane-lines"] > 0
    attacked = Ld3Defense(DefenseConfig())  # the MSF 1 m off where the lines are withheld: odometry still sees it
    _drive(attacked, corner, 9.4, msf_offset=1.0, lines_offset=1.0)
    assert attacked.detection_time is not None


def test_paper_mode_reads_every_line_as_before(corner):
    paper = Ld3Defense(DefenseConfig(**PAPER_MODE))
    _drive(paper, corner, 9.4, msf_offset=0.0, lines_offset=1.0)
    assert paper.detection_time is not None
    assert paper.faults.counts["corner-lines"] == 0


def test_the_radius_is_a_fail_closed_key():
    with pytest.raises(ValueError, match="fail_closed = false"):
        DefenseConfig(fail_closed=False, corner_radius=10.0)
