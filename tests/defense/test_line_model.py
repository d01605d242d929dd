"""The lines' model against the map's lane ahead: where a detected line's offset at the car is evidence, and
LD3 (fail-closed) withholding the others without losing the check of the MSF pose."""

import math

import numpy as np
import pytest

from testbed.defense.config import PAPER_MODE, DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.line_model import followable_lines, line_model_error
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


def test_the_model_follows_straights_and_wide_curves_not_a_sharp_corner_ahead(corner):
    assert max(line_model_error(corner, _on_lane(40.0), 0, 30.0)) < 1e-6
    wide = _map(Straight(50.0), Arc(200.0, 150.0))
    assert max(line_model_error(wide, _on_lane(50.0), 0, 30.0)) < 0.01
    assert min(line_model_error(corner, _on_lane(CORNER_AT - 15.0), 0, 30.0)) > 0.5
    assert line_model_error(_map(Straight(60.0)), _on_lane(55.0), 0, 30.0) == (0.0, 0.0)  # the map ends: kept


def test_a_line_that_leaves_the_view_within_a_few_metres_is_not_followable():
    hairpin = _map(Straight(50.0), Arc(11.0, 11.0 * math.pi), Straight(50.0))
    # at the hairpin's start the left line (radius 9.25 m) has turned 45° from the car within 7.3 m
    left, right = line_model_error(hairpin, _on_lane(50.0), 0, 30.0)
    assert left == math.inf and right < math.inf


def test_withheld_lines_are_removed_and_kept_ones_are_the_detection_s_own(corner):
    ld = _lines(0.0, WIDTH / 2, -WIDTH / 2)
    kept, withheld = followable_lines(ld, corner, _on_lane(40.0), 0, 0.1)
    assert kept is ld and withheld == []
    kept, withheld = followable_lines(ld, corner, _on_lane(CORNER_AT - 15.0), 0, 0.1)
    assert kept.left is None and kept.right is None and kept.left_prob == kept.right_prob == 0.0
    assert [w.split()[0] for w in withheld] == ["left", "right"]


def _drive(defense: Ld3Defense, smap: TrackMap, until: float, msf_offset: float, lines_offset: float) -> None:
    """A car centred on the lane at 10 m/s along the straight; odometry at 40 Hz, detections at 20 Hz. Once the
    corner is within 20 m the MSF pose is `msf_offset` left of the car and the lines read the car `lines_offset`
    left of where it is (a detector's extrapolation error)."""
    dt, speed = 0.025, 10.0
    for k in range(int(until / dt) + 1):
        t = k * dt
        defense.on_odometry(t, speed, 0.0)
        if k % 2:
            continue
        x = 5.0 + speed * t
        near = CORNER_AT - x < 20.0
        err = lines_offset if near else 0.0
        ld = _lines(t, WIDTH / 2 - err, -WIDTH / 2 - err)
        est = LocalizationEstimate(t, Pose(x, msf_offset if near else 0.0, 0.0), np.eye(3) * 0.01)
        defense.on_lane_detection(ld, est, smap)


def test_fail_closed_ld3_withholds_the_lines_a_corner_bends_and_checks_the_msf_by_odometry(corner):
    benign = Ld3Defense(DefenseConfig())
    _drive(benign, corner, 9.0, msf_offset=0.0, lines_offset=1.0)
    assert benign.detection_time is None
    assert benign.faults.counts["line-beyond-model"] > 0 and benign.faults.counts["no-lane-lines"] > 0
    attacked = Ld3Defense(DefenseConfig())  # the MSF 1 m off where the lines are withheld: odometry still sees it
    _drive(attacked, corner, 9.0, msf_offset=1.0, lines_offset=1.0)
    assert attacked.detection_time is not None


def test_paper_mode_reads_every_line_as_before(corner):
    paper = Ld3Defense(DefenseConfig(**PAPER_MODE))
    _drive(paper, corner, 9.0, msf_offset=0.0, lines_offset=1.0)
    assert paper.detection_time is not None
    assert paper.faults.counts["line-beyond-model"] == 0


def test_the_tolerance_is_a_fail_closed_key():
    with pytest.raises(ValueError, match="fail_closed = false"):
        DefenseConfig(fail_closed=False, line_model_tol=0.2)
