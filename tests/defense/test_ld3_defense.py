import dataclasses
import logging
import math

import numpy as np
import pytest

from testbed.defense.config import PAPER_CUSUM, DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.naive_ar import NaiveArDefense
from testbed.defense.no_defense import NoDefense
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tests.defense.fake_map import FakeStraightMap
from tracks.pose import Pose

HALF = 1.75  # half of the 3.5 m lane
PAPER_FRONT_END = {**PAPER_CUSUM, "fail_closed": False}
"""The paper's CUSUM with the paper mode's skipped updates, intersection resets and MSF-carried fused pose."""


def lane_det(t, phys_dev, prob=0.9):
    """Ideal LD for a vehicle `phys_dev` left of the lane-0 centre, heading along the lane."""
    return LaneDetection(
        t,
        np.array([HALF - phys_dev, 0, 0, 0.0]),
        np.array([-HALF - phys_dev, 0, 0, 0.0]),
        prob,
        prob,
        (0.0, 40.0),
    )


def msf_at(t, x, y, yaw=0.0):
    return LocalizationEstimate(t, Pose(x, y, yaw), np.eye(3) * 0.01)


def test_detection_index_on_a_drifting_msf():
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(**PAPER_CUSUM))
    # vehicle physically centred (D_LD = 0); D_MSF = 0, 0.5, 0.7, 0.75
    # S = 0, 0, 0.1 (not > 0.1), 0.1 + 0.15 = 0.25 > 0.1 -> alarm at the 4th detection (t = 0.15)
    modes = []
    for i, y in enumerate([0.0, 0.5, 0.7, 0.75]):
        d.on_lane_detection(lane_det(0.05 * i, 0.0), msf_at(0.05 * i, 0.5 * i, y), smap)
        modes.append((d.mode, d.stop_decel))
    assert modes == [("normal", None)] * 3 + [("ar", 4.0)]
    s = d.status()
    assert s.detected and s.detection_time == pytest.approx(0.15)
    assert s.cusum == pytest.approx(0.25)
    assert (s.d_msf, s.d_ld) == pytest.approx((0.75, 0.0))
    assert s.fused_dev is not None and s.kalman_gain_msf is not None and s.kalman_gain_ld is not None


def test_intersection_disables_detection_and_resets_cusum():
    smap = FakeStraightMap(intersections=((100.0, 120.0),))
    d = Ld3Defense(DefenseConfig(**PAPER_FRONT_END))
    off = 0.7  # constant |D_MSF - D_LD| = 0.7: S grows by 0.1 per detection outside intersections
    d.on_lane_detection(lane_det(0.0, 0.0), msf_at(0.0, 90.0, off), smap)  # S = 0.1
    d.on_lane_detection(lane_det(0.1, 0.0), msf_at(0.1, 110.0, off), smap)  # inside: skipped
    assert d.status().cusum == pytest.approx(0.1)
    d.on_lane_detection(lane_det(0.2, 0.0), msf_at(0.2, 125.0, off), smap)  # reset, then S = 0.1
    assert not d.status().detected  # without the reset S would be 0.2 > 0.1
    d.on_lane_detection(lane_det(0.3, 0.0), msf_at(0.3, 126.0, off), smap)  # S = 0.2 > 0.1
    assert d.status().detected and d.status().detection_time == 0.3


def alarmed_ld3(smap):
    d = Ld3Defense(DefenseConfig(**PAPER_FRONT_END))
    d.on_lane_detection(lane_det(0.0, 0.0), msf_at(0.0, 0.0, 1.0), smap)  # S = 1.0 - 0.6 = 0.4 -> alarm
    assert d.mode == "ar"
    return d


def test_ar_pose_is_fused_deviation_on_the_locked_ego_lane():
    smap = FakeStraightMap()
    d = alarmed_ld3(smap)
    # MSF drifts towards lane 1 (centre y = 3.5); the physical car is 0.1 m left of the lane-0 centre
    for i, y in enumerate([1.5, 2.0, 2.5]):
        d.on_lane_detection(lane_det(0.05 * (i + 1), 0.1), msf_at(0.05 * (i + 1), 5.0, y), smap)
    s = d.status()
    assert s.d_msf == pytest.approx(2.5)  # measured against lane 0, not the nearer lane 1
    assert s.kalman_gain_msf < s.kalman_gain_ld
    pose = d.pose_for_control(msf_at(0.2, 7.0, 2.5, yaw=0.02), smap)
    # lane 0 centreline point (7, 0) shifted by the fused d along +y, MSF yaw
    assert (pose.x, pose.y, pose.yaw) == pytest.approx((7.0, s.fused_dev, 0.02))
    assert abs(s.fused_dev) < 1.0


def test_ar_pose_when_msf_leaves_the_map_follows_msf_motion():
    smap = FakeStraightMap()
    d = alarmed_ld3(smap)
    good = d.pose_for_control(msf_at(0.0, 0.0, 1.0), smap)
    # y = 3.0 is 3.0 m from lane 0 > 1.75 + 1.0: lane_point raises OffMapError
    moved = d.pose_for_control(msf_at(0.1, 2.0, 3.0), smap)
    assert (moved.x, moved.y) == pytest.approx((good.x + 2.0, good.y + 2.0))
    # a NaN MSF pose holds the last pose handed out
    assert d.pose_for_control(msf_at(0.2, math.nan, 0.0), smap) == moved


def test_bad_inputs_never_raise_and_are_logged(caplog):
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(**PAPER_FRONT_END))
    with caplog.at_level(logging.DEBUG, logger="testbed.defense"):
        d.on_lane_detection(lane_det(0.0, 0.0), msf_at(0.0, 0.0, math.nan), smap)  # NaN pose
        d.on_lane_detection(lane_det(0.05, 0.0), msf_at(0.05, 0.0, 20.0), smap)  # off the map
        d.on_lane_detection(LaneDetection.empty(0.1), msf_at(0.1, 0.0, 0.0), smap)  # no D_LD yet
        assert d.status().cusum == 0.0 and d.status().d_ld is None
        d.on_lane_detection(lane_det(0.15, 0.3), msf_at(0.15, 1.0, 0.3), smap)  # good: D_LD = 0.3
        nan_lines = LaneDetection(0.2, np.full(4, math.nan), None, 0.9, 0.9, (0.0, 0.0))
        d.on_lane_detection(nan_lines, msf_at(0.2, 2.0, 0.3), smap)  # reuses D_LD = 0.3
    assert d.status().d_ld == pytest.approx(0.3) and d.status().cusum == 0.0
    assert d.faults.counts == {"nan-pose": 1, "off-map": 1, "no-lane-lines": 2}
    assert sum(r.levelno == logging.WARNING for r in caplog.records) == 4


def test_naive_ar_stops_at_max_decel_on_msf():
    smap = FakeStraightMap()
    d = NaiveArDefense(DefenseConfig(**PAPER_CUSUM, max_decel=7.5))
    msf = msf_at(0.0, 0.0, 1.0)
    d.on_lane_detection(lane_det(0.0, 0.0), msf, smap)
    assert d.mode == "ar" and d.stop_decel == 7.5
    assert d.pose_for_control(msf, smap) == msf.pose
    assert d.status().fused_dev is None and d.status().detection_time == 0.0


def test_no_defense_never_reacts():
    smap = FakeStraightMap()
    d = NoDefense()
    msf = msf_at(0.0, 0.0, 1.0)
    d.on_lane_detection(lane_det(0.0, 0.0), msf, smap)
    assert d.mode == "normal" and d.stop_decel is None and not d.status().detected
    assert d.pose_for_control(msf, smap) == msf.pose


def test_reported_p_sources_feed_alg4():
    """p_source = reported: P^MSF = the MSF's lateral variance across the lane, P^LD = the c0 variance of the line
    Alg. 3 used; Alg. 4 then gives R = λ f + (1 − λ) P (hand-computed below, λ = 0.5, w = 3). The response gate
    is opened wide so that the 1 m MSF offset stays in Alg. 2 (the gate has tests of its own)."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(**PAPER_CUSUM, p_source="reported", lam=0.5, window=3, response_gate=5.0))
    cov = np.diag([0.04, 0.09, 0.01])  # lane heads +x: the lateral variance is cov[1, 1]

    def det(t, phys):
        return dataclasses.replace(lane_det(t, phys), left_var=0.0025, right_var=0.01)

    d.on_lane_detection(det(0.0, 0.0), LocalizationEstimate(0.0, Pose(0.0, 1.0, 0.0), cov), smap)  # alarm
    s = d.status()
    # s_msf = 1.0, s_ld = 1e-3 (floor; Alg. 3 ties on the left line), g = sqrt(1e-3)
    g = math.sqrt(1e-3)
    assert (s.r_msf, s.r_ld) == pytest.approx((0.5 * 1.0 / g + 0.5 * 0.09, 0.5 * 1e-3 / g + 0.5 * 0.0025))
    # the car 0.3 m right: the right line is nearer and its variance 0.01 is used
    d.on_lane_detection(det(0.05, -0.3), LocalizationEstimate(0.05, Pose(1.0, 1.2, 0.0), cov), smap)
    s = d.status()
    s_msf, s_ld = 1.0 + 1.2, 0.0 + 0.3  # |D_LD| = 0 then 0.3: the floor applies to the sum, not each value
    g = math.sqrt(s_msf * s_ld)
    assert (s.r_msf, s.r_ld) == pytest.approx((0.5 * s_msf / g + 0.5 * 0.09, 0.5 * s_ld / g + 0.5 * 0.01))


def test_constant_p_sources_ignore_what_the_sources_report():
    smap = FakeStraightMap()  # the gate opened wide as above: the 1 m MSF offset stays in Alg. 2
    d = Ld3Defense(DefenseConfig(**PAPER_CUSUM, lam=0.5, p_msf=0.2, p_ld=0.4, response_gate=5.0))
    ld = dataclasses.replace(lane_det(0.0, 0.0), left_var=9.0, right_var=9.0)
    d.on_lane_detection(ld, LocalizationEstimate(0.0, Pose(0.0, 1.0, 0.0), np.eye(3) * 5.0), smap)
    g = math.sqrt(1e-3)
    assert (d.status().r_msf, d.status().r_ld) == pytest.approx((0.5 / g + 0.1, 0.5 * 1e-3 / g + 0.2))


@pytest.mark.parametrize(("heading", "expected_yaw"), [("msf", 0.03), ("lane", 0.0), ("ld", -0.01)])
def test_ar_pose_heading_sources(heading, expected_yaw):
    """The car is 0.01 rad right of the lane (the lines say so); the MSF yaw says 0.03 left."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(**PAPER_CUSUM, heading=heading))
    slope = math.tan(0.01)
    ld = LaneDetection(0.0, np.array([HALF, slope, 0, 0.0]), np.array([-HALF, slope, 0, 0.0]), 0.9, 0.9, (0.0, 40.0))
    d.on_lane_detection(ld, msf_at(0.0, 0.0, 1.0, yaw=0.03), smap)
    assert d.mode == "ar"
    pose = d.pose_for_control(msf_at(0.0, 0.0, 1.0, yaw=0.03), smap)
    assert pose.yaw == pytest.approx(expected_yaw)
    assert d.status().heading_rel == pytest.approx(expected_yaw)


def test_an_alarm_on_an_msf_pose_beyond_half_a_lane_keeps_the_car_s_own_lane():
    """A one-detection burst puts the MSF pose 2.2 m left, nearer lane 1's centre (3.5 m) than lane 0's: the
    response must stay on lane 0, where MSF and lines last agreed, or it steers the car a lane width away."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(**PAPER_CUSUM))
    for i in range(3):  # MSF and lines agree: the car 0.05 m left of the lane-0 centre
        d.on_lane_detection(lane_det(0.05 * i, 0.05), msf_at(0.05 * i, 0.5 * i, 0.05), smap)
    assert d.mode == "normal"
    d.on_lane_detection(lane_det(0.15, 0.05), msf_at(0.15, 1.5, 2.2), smap)
    # against lane 1, D_MSF = -1.3 and |D_MSF - D_LD| = 1.35: S = 0.75 > 0.1
    assert d.mode == "ar" and d.monitor.ego_lane == 0
    assert d.status().d_msf == pytest.approx(-1.3)  # Alg. 1's own D_MSF, against the nearest lane
    assert d.fusion.last is not None and d.fusion.last.d > 0.0  # fused on lane 0: between 0.05 and 2.2
    pose = d.pose_for_control(msf_at(0.16, 1.6, 0.05), smap)
    assert pose.y == pytest.approx(d.fusion.last.d) and abs(pose.y) < HALF  # on lane 0, not near y = 3.5


def test_without_any_agreement_the_ego_lane_is_the_msf_lane_at_the_alarm():
    smap = FakeStraightMap()
    d = alarmed_ld3(smap)  # alarmed on its first detection, MSF 1 m left on lane 0
    assert d.monitor.ego_lane == 0
