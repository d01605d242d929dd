"""LD3's fail-closed rules on hand-built drives: odometry dead reckoning, off-map MSF poses as evidence, the
response pose carried by odometry (never by the MSF), the check through intersections, the ego lane an MSF
jump of a lane width cannot move, faults in the summary; and the paper mode's behaviour where they differ."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np
import pytest

from testbed.defense.alarmed import Ld3AlarmedDefense
from testbed.defense.config import DefenseConfig
from testbed.defense.faults import FaultLog, FaultRecord
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.naive_ar import NaiveArDefense
from testbed.defense.odometry import DeadReckoning, advance, drift_allowance, into_heading_span, into_span, step_toward
from testbed.eval.run.scenario import load_scenario
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.sensors import ImuModel
from tests.defense.fake_map import FakeStraightMap
from tracks.pose import Pose

HALF = 1.75  # half of the 3.5 m lane
ZONE = (100.0, 130.0)  # an intersection along x
PAPER = {"fail_closed": False}


def lines(t: float, dev: float, slope: float = 0.0) -> LaneDetection:
    """Ideal lines for a car `dev` m left of the lane-0 centre, parallel to the lane, or turned by `slope` (their
    offset at the car kept: lines a road patch bends)."""
    return LaneDetection(t, np.array([HALF - dev, slope, 0, 0.0]), np.array([-HALF - dev, slope, 0, 0.0]), 0.9, 0.9,
                         (0.0, 40.0))


class Drive:
    """A car at `speed` along lane 0 (+x) of a straight road, `dev` m left of its centre; odometry every 10 ms,
    a lane detection every 50 ms (none inside an intersection). `msf(t, x)` is the MSF pose's lateral
    offset from the car (an attacker's shift), `yaw(t, x)` its yaw (the car's is 0)."""

    def __init__(self, defense: Ld3AlarmedDefense, smap: FakeStraightMap, x0: float = 50.0, speed: float = 10.0,
                 dev: float = 0.0, gyro_bias: float = 0.0) -> None:
        self.defense, self.smap, self.x0, self.speed, self.dev = defense, smap, x0, speed, dev
        self.gyro_bias = gyro_bias
        self.ticks = 0
        self.control: list[Pose] = []
        self.alarm_x: float | None = None
        self.alarm_tick: int | None = None

    @property
    def t(self) -> float:
        return round(self.ticks * 0.01, 9)

    @property
    def x(self) -> float:
        return self.x0 + self.speed * self.t

    def run(self, seconds: float, msf: Callable[[float, float], float] = lambda t, x: 0.0,
            yaw: Callable[[float, float], float] = lambda t, x: 0.0, slope: float = 0.0) -> Drive:
        for _ in range(round(seconds * 100)):
            self.defense.on_odometry(self.t, self.speed, self.gyro_bias)
            est = LocalizationEstimate(self.t, Pose(self.x, self.dev + msf(self.t, self.x), yaw(self.t, self.x)),
                                       np.eye(3) * 0.01)
            if self.ticks % 5 == 0:
                inside = any(lo <= self.x <= hi for lo, hi in self.smap.intersections)
                ld = LaneDetection.empty(self.t) if inside else lines(self.t, self.dev, slope)
                self.defense.on_lane_detection(ld, est, self.smap)
                if self.alarm_x is None and self.defense.mode == "ar":
                    self.alarm_x, self.alarm_tick = self.x, self.ticks
            self.control.append(self.defense.pose_for_control(est, self.smap))
            self.ticks += 1
        return self


# --- dead reckoning ---------------------------------------------------------------------------------------

def test_dead_reckoning_on_a_straight_and_on_a_circle():
    assert advance(Pose(1.0, 2.0, 0.5), 2.0, 3.0, 0.0) == pytest.approx(
        (1.0 + 6.0 * math.cos(0.5), 2.0 + 6.0 * math.sin(0.5), 0.5))
    # a quarter circle of radius 10 m turning left: from (0, 0) heading +x to (10, 10) heading +y
    odo = DeadReckoning()
    odo.on_odometry(0.0, 5.0, 0.5)
    odo.anchor(Pose(0.0, 0.0, 0.0))
    steps = 100
    for i in range(1, steps + 1):
        odo.on_odometry(i * (math.pi / 2 / 0.5) / steps, 5.0, 0.5)
    assert odo.pose == pytest.approx((10.0, 10.0, math.pi / 2))


def test_dead_reckoning_carries_a_reference_point_ahead_of_the_rear_axle_on_its_circle():
    """The rear axle on a circle of radius R: a point `lever` ahead stays on the circle of radius
    sqrt(R² + lever²) about the same centre (a unicycle at that point would leave it by lever·ω per second)."""
    radius, lever, speed = 7.0, 1.4, 5.0
    rate = speed / radius
    odo, unicycle = DeadReckoning(lever), DeadReckoning()
    start = Pose(lever, 0.0, 0.0)  # rear axle at the origin heading +x: the centre is (0, R)
    for o in (odo, unicycle):
        o.on_odometry(0.0, speed, rate)
        o.anchor(start)
    for i in range(1, 41):  # 1 s at 40 Hz
        odo.on_odometry(i * 0.025, speed, rate)
        unicycle.on_odometry(i * 0.025, speed, rate)
    def off_circle(p):
        return math.hypot(p.x, p.y - radius) - math.hypot(radius, lever)
    assert abs(off_circle(odo.pose)) < 1e-9 and odo.pose.yaw == pytest.approx(rate)
    assert abs(off_circle(unicycle.pose)) > 0.5  # the drift a lever removes


def test_dead_reckoning_integrates_the_mean_of_two_samples_and_refuses_bad_ones():
    odo = DeadReckoning()
    assert odo.on_odometry(0.0, 10.0, 0.0) and odo.pose is None  # a clock, no pose before the anchor
    odo.anchor(Pose(0.0, 0.0, 0.0))
    assert odo.on_odometry(1.0, 12.0, 0.0) and odo.pose == pytest.approx((11.0, 0.0, 0.0))
    assert not odo.on_odometry(1.0, 12.0, 0.0) and not odo.on_odometry(1.1, math.nan, 0.0)
    assert odo.pose == pytest.approx((11.0, 0.0, 0.0)) and odo.samples == 2


def test_an_anchor_moves_the_yaw_only_its_share_of_the_way():
    odo = DeadReckoning()
    odo.anchor(Pose(1.0, 2.0, 0.1), 0.1)
    assert odo.pose == (1.0, 2.0, 0.1)  # the first anchor sets it all
    odo.anchor(Pose(3.0, 4.0, 0.3), 0.1)
    assert odo.pose == pytest.approx((3.0, 4.0, 0.12))


def test_imu_grade_yaw_rate_noise_drifts_far_less_than_b_across_an_intersection():
    """A 30-m zone at 12 m/s on a yaw rate with the IMU model's noise and a 3-sigma gyro bias."""
    imu, rng = ImuModel(), np.random.default_rng(0)
    odo = DeadReckoning()
    odo.on_odometry(0.0, 12.0, 0.0)
    odo.anchor(Pose(0.0, 0.0, 0.0))
    for i in range(1, 251):
        odo.on_odometry(i * 0.01, 12.0, 3 * imu.gyro_bias_std + imu.gyro_std * rng.normal())
    assert odo.pose.x == pytest.approx(30.0, abs=0.01)
    assert abs(odo.pose.y) < 0.5 * DefenseConfig().b


# --- off-map MSF poses ------------------------------------------------------------------------------------

def test_odometry_follows_lines_that_agree_with_it_while_the_msf_is_held_just_above_b():
    """An MSF held 0.205 m off (b = 0.2: never agreeing, S growing 5 mm a detection) for 15 s on a gyro biased by
    2 mrad/s, which alone would carry the dead-reckoned pose metres off: it stays on the lines."""
    defense = Ld3Defense(DefenseConfig())
    drive = Drive(defense, FakeStraightMap(), gyro_bias=0.002).run(2.0)
    drive.run(15.0, msf=lambda t, x: 0.205)
    assert defense.mode == "normal"
    reckoned = defense.monitor.reckoned
    assert abs(drive.smap.lane_dev(reckoned, 0)) < 0.02 and abs(reckoned.x - drive.x) < 0.5


@pytest.mark.parametrize("config", [{}, PAPER])
def test_an_msf_shift_beside_the_lines_is_named_the_lateral_check_against_the_lines(config):
    """A 1 m MSF shift with the lines in view: Alg. 1's CUSUM alarms on D_MSF − D_LD, in both modes, and the status
    names that check."""
    d = Ld3Defense(DefenseConfig(**config))
    Drive(d, FakeStraightMap()).run(1.0).run(1.0, lambda t, x: 1.0)
    assert d.mode == "ar" and d.status().alarm_check == "lateral-lines"


@pytest.mark.parametrize("bad", [30.0, math.nan])
def test_an_msf_pose_the_map_cannot_place_alarms_at_once(bad):
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig())
    drive = Drive(d, smap).run(1.0)
    assert d.mode == "normal"
    drive.run(0.1, lambda t, x: bad)
    assert d.mode == "ar" and d.status().detection_time == pytest.approx(1.0)
    assert d.status().cusum == pytest.approx(3.5 - d.config.b)  # one lane width, less b
    assert d.status().alarm_check == "lateral-unplaced"
    kind = "off-map" if math.isfinite(bad) else "nan-pose"
    assert {r.kind: r.count for r in d.fault_records()}[kind] >= 1


def test_an_msf_yaw_bias_before_the_zone_does_not_tilt_the_check():
    """MSF position on the car, its yaw 0.05 rad off over the last 12 m before the zone, then moved 0.05 m per
    metre inside it: what a check anchored on the MSF yaw would follow. The dead-reckoned yaw follows the lines'
    heading (the car is parallel to the lane), so the shift is seen inside the zone (the heading check, which
    catches the planting itself, switched off)."""
    smap = FakeStraightMap(intersections=(ZONE,))
    d = Ld3Defense(DefenseConfig(heading_tau=1e9))
    drive = Drive(d, smap)
    drive.run(5.0, yaw=lambda t, x: 0.05 if x >= 88.0 else 0.0)
    assert d.mode == "normal" and abs(d.monitor.odometry.pose.yaw) < 1e-9
    drive.run(3.0, lambda t, x: 0.05 * (x - 100.0), lambda t, x: 0.05)
    assert d.mode == "ar" and ZONE[0] <= drive.alarm_x <= ZONE[1]


def test_the_heading_check_catches_a_biased_msf_yaw_with_a_true_position():
    """A 0.05 rad MSF yaw bias, position true: the lateral CUSUM sees nothing, the heading check alarms within
    (0.3 / (0.05 − 0.03) =) 15 detections of the bias; a bias inside heading_b never alarms."""
    smap = FakeStraightMap(intersections=(ZONE,))
    d = Ld3Defense(DefenseConfig())
    drive = Drive(d, smap).run(4.0, yaw=lambda t, x: 0.05 if x >= 60.0 else 0.0)
    assert d.mode == "ar" and 60.0 <= drive.alarm_x <= 60.0 + 16 * drive.speed / 20.0 and d.status().cusum == 0.0
    assert d.status().alarm_check == "heading-lines"
    quiet = Ld3Defense(DefenseConfig())
    Drive(quiet, smap).run(4.0, yaw=lambda t, x: 0.025 if x >= 60.0 else 0.0)
    assert quiet.mode == "normal" and quiet.status().alarm_check is None
    with pytest.raises(ValueError, match="fail_closed = false"):
        DefenseConfig(**PAPER, heading_b=0.05)


def test_lines_turned_off_the_msf_heading_do_not_turn_the_dead_reckoned_yaw():
    """Lines bent 0.08 or 0.02 rad, their offset at the car true, beside a true MSF (the heading check, which catches
    a bend past heading_b, switched off): the dead-reckoned yaw, the gyro's 0 inside the interval between the MSF's
    heading and the lines', stays there."""
    smap = FakeStraightMap()
    for slope in (0.08, 0.02):
        bent = Ld3Defense(DefenseConfig(heading_tau=1e9))
        Drive(bent, smap).run(1.0).run(3.0, slope=slope)
        assert bent.mode == "normal" and abs(bent.monitor.odometry.pose.yaw) < 1e-9


@pytest.mark.parametrize(("slope", "low", "high"), [(0.0, 0.0, 0.001), (0.02, 0.0, 0.001), (-0.02, 0.009, 0.011)])
def test_a_drifting_gyro_is_turned_back_into_the_interval_between_the_msf_and_the_lines(slope, low, high):
    """A gyro 1 mrad/s off carries the dead-reckoned yaw out of the interval between a true MSF's heading (0) and the
    lines' (true, or bent 0.02 rad to the other side): the anchors turn it back at line_yaw_rate, where 10 s of the gyro
    alone leave it 0.01 rad off. Lines bent to the side the gyro drifts widen the interval: the yaw is left to it."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(heading_tau=1e9, yaw_margin=0.0))
    Drive(d, smap, gyro_bias=0.001).run(1.0).run(10.0, slope=slope)
    assert d.mode == "normal" and low < d.monitor.odometry.pose.yaw < high


@pytest.mark.parametrize(("slope", "low", "high"), [(0.0, 0.0, 0.001), (0.02, 0.0095, 0.0105)])
def test_with_the_margin_a_drifting_gyro_is_turned_back_to_within_the_sources_disagreement(slope, low, high):
    """The same gyro for 20 s (0.02 rad alone) with the default `yaw_margin`: where the sources agree the interval
    is not widened and the yaw is turned back into it; lines bent 0.02 rad widen it by their disagreement up to the
    margin (0.01 rad), and the yaw is turned back to that edge."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(heading_tau=1e9))
    Drive(d, smap, gyro_bias=0.001).run(1.0).run(20.0, slope=slope)
    assert d.config.yaw_margin == 0.01 and d.mode == "normal" and low < d.monitor.odometry.pose.yaw < high


@pytest.mark.parametrize(("margin", "low", "high"), [(None, -0.0005, 0.0005), (0.0, -0.0005, 0.0005)])
def test_the_honest_msf_heading_s_wander_does_not_ratchet_the_yaw_towards_bent_lines(margin, low, high):
    """A true MSF whose heading wanders ±6 mrad (as the MSF's does on benign drives), lines bent 0.03 rad to one
    side for 20 s (the heading check off), an honest gyro: the yaw stays the gyro's, with the default margin and
    without one. Were the span the two headings' alone, each swing of the MSF's heading towards the lines would turn
    it, none back: it would ratchet to the swing's edge, and a response steered on it drift v × 6 mrad a second; the
    lane's heading in the span holds the gyro's yaw along the lane."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(heading_tau=1e9, **({} if margin is None else {"yaw_margin": margin})))
    wander = lambda t, x: -0.006 * math.sin(2.0 * math.pi * t / 3.0)  # noqa: E731
    Drive(d, smap).run(1.0).run(20.0, yaw=wander, slope=-0.03)
    assert d.mode == "normal" and low < d.monitor.odometry.pose.yaw < high


def test_an_msf_heading_off_to_the_side_lines_are_bent_does_not_turn_the_yaw_off_the_lane():
    """A true MSF position whose heading errs 5 mrad for 10 s (an honest MSF's does for seconds at highway speed),
    lines bent 8 mrad to the same side, an honest gyro (no bias learnt): the dead-reckoned yaw, the gyro's 0 along the
    lane, stays there. Turned into the sources' interval alone it would go to the MSF's 5 mrad less their 3 mrad of
    disagreement and carry the dead-reckoned pose, and the response's reference with it, sideways at v × 2 mrad."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(odometry_bias_span=0.0))
    Drive(d, smap).run(1.0).run(10.0, yaw=lambda t, x: 0.005, slope=-0.008)
    assert d.mode == "normal" and d.monitor.odometry.pose.yaw == 0.0


def test_lines_creeping_from_a_true_msf_after_the_alarm_do_not_drag_the_reference():
    """Lines that creep away from a true MSF at 0.1 m/s raise the alarm and creep on for 10 s more: the response's
    reference, which starts at the trusted pose the creep pulled towards the lines, follows Alg. 2's fused deviation
    (the steady MSF weighed over the creeping lines) back towards the car until the lines leave the gate; moved towards
    the lines at `line_rate` it would go the other way, 0.06 m farther with them. The MSF is never disowned and the
    control pose stays at the car."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig())
    drive = Drive(d, smap).run(1.0)
    while d.mode == "normal" and drive.t < 10.0:
        drive.dev += 0.005  # the lines' offset from the car's lane; the MSF held at the car, 0
        drive.run(0.05, lambda t, x: -drive.dev)
    assert d.mode == "ar" and d.status().alarm_check == "lateral-lines"
    at_alarm = float(smap.lane_dev(d._reference.pose, 0))
    for _ in range(200):
        drive.dev += 0.005
        drive.run(0.05, lambda t, x: -drive.dev)
    assert drive.dev > 1.2 and d.faults.counts.get("msf-disowned", 0) == 0 and d.faults.counts["ld-gated"] > 100
    assert at_alarm > 0.05 and float(smap.lane_dev(d._reference.pose, 0)) < at_alarm - 0.03
    assert abs(drive.control[-1].y) < 0.01


def test_the_trusted_pose_stays_between_the_sources_however_long_they_are_held_apart():
    """An MSF held 0.15 m off the true lines (between half b and b: no anchor of the trusted pose, no alarm) for 20 s,
    odometry's yaw rate 0.002 rad/s off and no bias learnt: carried alone the trusted pose would drift metres; it
    stays within half b of the interval between D_MSF and D_LD."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(odometry_bias_span=0.0))
    drive = Drive(d, smap, gyro_bias=0.002).run(1.0)
    for _ in range(20):
        drive.run(1.0, lambda t, x: 0.15)
        pose = d.monitor.trusted.pose
        carried = drive.speed * 0.05 * abs(math.sin(pose.yaw))  # odometry since the last detection, 50 ms ago at most
        assert d.mode == "normal" and -0.1 - carried <= float(smap.lane_dev(pose, 0)) <= 0.25 + carried


def test_naive_ar_shares_the_fail_closed_detection():
    smap = FakeStraightMap(intersections=(ZONE,))
    d = NaiveArDefense(DefenseConfig())
    Drive(d, smap).run(5.2).run(1.0, lambda t, x: 2.0)  # shifted inside the zone
    assert d.mode == "ar" and d.stop_decel == d.config.max_decel


def test_paper_mode_skips_off_map_updates():
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(**PAPER))
    Drive(d, smap).run(1.0).run(5.0, lambda t, x: 30.0)
    assert d.mode == "normal" and d.status().cusum == 0.0
    assert d.faults.counts["off-map"] == 100


# --- the response pose --------------------------------------------------------------------------------------

def test_the_response_pose_is_carried_by_odometry_not_by_the_msf():
    """Alarmed by an MSF pose 30 m to the left, the response never follows it: the control pose stays in lane,
    moves along at the odometry's speed, and Alg. 2 fuses D_LD alone (the car is 0.3 m left)."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig())
    drive = Drive(d, smap, dev=0.3).run(1.0)
    start = len(drive.control)
    drive.run(3.0, lambda t, x: 30.0 + 5.0 * (t - 1.0))  # and it keeps running away sideways
    assert d.mode == "ar"
    poses = drive.control[start:]
    assert all(abs(p.y) < HALF and abs(p.yaw) < 0.05 for p in poses)
    assert [p.x for p in poses] == pytest.approx([drive.alarm_x + 0.1 * i for i in range(len(poses))], abs=1e-6)
    step = d.fusion.last
    assert step.gain_msf == 0.0 and math.isinf(step.r_msf) and step.d == pytest.approx(0.3, abs=0.05)
    assert poses[-1].y == pytest.approx(step.d, abs=1e-9)
    assert d.faults.counts["msf-left-out"] > 0


def test_an_msf_pose_moved_30_m_during_the_response_leaves_the_control_pose_in_lane():
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig())
    drive = Drive(d, smap, dev=-0.2).run(1.0).run(0.5, lambda t, x: 1.2)  # 1.2 m off: alarm on the 3rd detection
    assert d.mode == "ar" and drive.alarm_x is not None
    start = len(drive.control)
    drive.run(2.0, lambda t, x: 30.0)
    assert all(abs(p.y - drive.dev) < 0.3 for p in drive.control[start:])
    assert drive.control[-1].x == pytest.approx(drive.x - 0.1, abs=1e-6)


def test_the_response_pose_station_is_the_odometry_s_not_the_msf_s():
    """An MSF pose dragged 40 m ahead of the car during the response does not move the control pose ahead."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig())
    drive = Drive(d, smap).run(1.0).run(0.1, lambda t, x: 30.0)
    assert d.mode == "ar"
    x_before = drive.control[-1].x
    d.on_odometry(drive.t, drive.speed, 0.0)
    far = LocalizationEstimate(drive.t, Pose(drive.x + 40.0, 0.5, 0.0), np.eye(3) * 0.01)
    d.on_lane_detection(lines(drive.t, 0.0), far, smap)
    assert d.pose_for_control(far, smap).x == pytest.approx(x_before + 0.1, abs=1e-6)


def test_paper_mode_carries_the_fused_pose_with_the_msf_motion():
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(b=0.6, tau=0.1, **PAPER))
    drive = Drive(d, smap).run(1.0).run(0.1, lambda t, x: 1.0)  # alarm on an on-map MSF pose 1 m left
    assert d.mode == "ar"
    drive.run(1.0, lambda t, x: 30.0)
    assert abs(drive.control[-1].y) > 25.0


# --- intersections and line gaps ------------------------------------------------------------------------------

def test_a_2_m_msf_shift_inside_an_intersection_is_detected_there():
    smap = FakeStraightMap(intersections=(ZONE,))
    d = Ld3Defense(DefenseConfig())
    drive = Drive(d, smap).run(5.2)  # x = 102: inside
    assert d.mode == "normal" and d.monitor.in_intersection
    drive.run(1.0, lambda t, x: 2.0)
    assert d.mode == "ar" and ZONE[0] <= drive.alarm_x <= ZONE[0] + 5.0
    assert d.faults.counts["gated-zone"] > 0 and d.status().alarm_check == "lateral-odometry"
    assert all(abs(p.y) < 0.1 for p in drive.control[drive.alarm_tick:])  # the response: on the car


def before_the_zone(t: float, x: float) -> float:
    """The MSF 0.25 m off the lines over the last second before the zone (x = 90 .. 100): S = 20 × 0.05 = 1.0."""
    return 0.25 if x >= 90.0 else 0.0


def test_paper_mode_misses_the_same_shift_and_resets_s_after_the_zone():
    smap = FakeStraightMap(intersections=(ZONE,))
    d = Ld3Defense(DefenseConfig(**PAPER))
    drive = Drive(d, smap).run(5.0, before_the_zone)
    assert d.status().cusum == pytest.approx(1.0) and d.mode == "normal"
    drive.run(3.0, lambda t, x: 2.0)  # x = 100 .. 130, shifted 2 m inside the zone: unchecked
    assert d.mode == "normal" and d.status().cusum == pytest.approx(1.0)
    drive.run(0.5)  # out of the zone, the MSF back on the car
    assert d.mode == "normal" and d.status().cusum == 0.0  # S reset on the way out


def test_a_benign_zone_keeps_s():
    """Inside the zone the MSF stays 0.19 m (< b) off the dead-reckoned pose: S drains by 0.01 a detection and
    leaves the zone at about 1.0 − 60 × 0.01 = 0.4, where the paper mode would reset it."""
    smap = FakeStraightMap(intersections=(ZONE,))
    d = Ld3Defense(DefenseConfig())
    drive = Drive(d, smap).run(5.0, before_the_zone)
    assert d.status().cusum == pytest.approx(1.0) and d.mode == "normal"
    drive.run(3.0, lambda t, x: 0.19)
    drive.run(0.1)  # out of the zone: the first detections drain S by b each
    assert d.mode == "normal" and not d.monitor.in_intersection
    assert d.status().cusum == pytest.approx(0.4 - 2 * d.config.b, abs=0.02)
    assert d.faults.counts["gated-zone"] > 50


def test_without_lines_the_msf_is_checked_against_odometry():
    """No valid line outside any zone (worn paint): a shift of the MSF there is still seen."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig())
    drive = Drive(d, smap).run(1.0)
    for _ in range(20):
        d.on_odometry(drive.t, drive.speed, 0.0)
        d.on_lane_detection(LaneDetection.empty(drive.t),
                            LocalizationEstimate(drive.t, Pose(drive.x, 1.0, 0.0), np.eye(3) * 0.01), smap)
        drive.ticks += 5
    assert d.mode == "ar" and d.faults.counts["no-lane-lines"] > 0


# --- the ego lane ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("fail_closed", "alarm"), [(True, True), (False, False)])
def test_an_msf_jump_of_one_lane_width_does_not_move_the_lane_checked(fail_closed, alarm):
    """Lane 1's centre is 3.5 m left: against the nearest lane the MSF deviation is unchanged, so the paper's
    check agrees with the lines and moves the last agreed lane; against the dead-reckoned pose's lane it is
    a lane width off."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(fail_closed=fail_closed))
    Drive(d, smap, dev=0.1).run(1.0).run(1.0, lambda t, x: 3.5)
    assert (d.mode == "ar") is alarm
    assert d.monitor._agreed_lane == (0 if fail_closed else 1)


# --- faults reach the summary -------------------------------------------------------------------------------

def test_fault_records_keep_first_and_last_occurrence_and_count():
    log = FaultLog(logging.getLogger("test"))
    log.report("off-map", 1.0, "first")
    log.report("nan-pose", 1.5, "other")
    log.report("off-map", 2.0, "second")
    assert log.records() == [FaultRecord("off-map", 1.0, "first", 2.0, 2),
                             FaultRecord("nan-pose", 1.5, "other", 1.5, 1)]


def test_fail_closed_is_a_key_ld3_and_naive_ar_read_and_others_refuse():
    for defense in ("ld3", "ld3-naive-ar"):
        sc = load_scenario("local").with_overrides(defense=defense, defense_params={"fail_closed": False})
        assert sc.defense_params == {"fail_closed": False}
    with pytest.raises(ValueError, match="fail_closed"):
        load_scenario("local").with_overrides(defense="savior", defense_params={"fail_closed": False})


def test_a_single_source_moves_a_reference_by_its_drift_allowance_at_most():
    assert drift_allowance(0.02, 2.0) == pytest.approx(0.04)
    assert drift_allowance(0.02, 0.0) == 0.0 and drift_allowance(0.02, -1.0) == 0.0  # no time, no move
    assert drift_allowance(0.0, math.inf) == 0.0  # a zero rate never moves it, however long ago the last anchor
    assert drift_allowance(math.inf, 0.0) == math.inf  # no limit at all, never NaN
    assert step_toward(0.1, 0.9, 0.04) == pytest.approx(0.14)
    assert step_toward(0.1, -0.9, 0.04) == pytest.approx(0.06)
    assert step_toward(0.1, 0.12, 0.04) == pytest.approx(0.12)
    assert step_toward(0.1, 0.9, math.inf) == pytest.approx(0.9)


def test_a_value_moved_into_the_span_of_two_readings():
    assert into_span(0.5, -0.1, 0.2) == 0.2 and into_span(-0.5, 0.2, -0.1) == -0.1  # either order
    assert into_span(0.05, -0.1, 0.2) == 0.05  # inside: left where it is
    assert into_span(0.5, -0.1, 0.2, margin=0.1) == pytest.approx(0.3)


def test_a_heading_moved_into_the_sources_span_widened_by_their_disagreement():
    assert into_heading_span(0.01, 0.0, 0.0, 0.01) == 0.0  # the sources agree: nothing widens their span
    assert into_heading_span(0.01, 0.0, 0.004, 0.01) == pytest.approx(0.008)  # widened by their 4 mrad
    assert into_heading_span(-0.05, 0.0, 0.03, 0.01) == pytest.approx(-0.01)  # by at most the margin
    assert into_heading_span(0.005, 0.0, -0.03, 0.01) == 0.005  # inside the widened span: left where it is


def test_the_span_of_two_headings_to_one_side_of_the_lane_reaches_back_to_the_lane_s():
    assert into_heading_span(0.002, 0.005, 0.004, 0.01) == 0.002  # between the lane's and theirs: left where it is
    assert into_heading_span(-0.003, 0.005, 0.004, 0.01) == pytest.approx(-0.001)  # turned to the lane's, widened
    assert into_heading_span(0.009, 0.005, 0.004, 0.01) == pytest.approx(0.006)  # the far side as before
    assert into_heading_span(0.003, -0.005, -0.006, 0.0) == 0.0  # the other side of the lane, no margin


@pytest.mark.parametrize(("msf_yaw", "slope", "expected"), [
    (0.0, 0.0, 0.0), (0.02, 0.0, 0.0), (0.0, -0.02, 0.0), (0.02, -0.01, 0.01), (0.01, -0.03, 0.01),
    (-0.01, -0.02, 0.0)])
def test_the_first_anchor_takes_the_middle_of_the_msf_s_the_lines_and_the_lane_s_heading(msf_yaw, slope, expected):
    """The first detection where MSF and lines agree across the lane anchors the dead-reckoned yaw at the middle of
    the MSF's heading, the lines' (bent by `slope`: −slope relative to the lane) and the lane's: one source off on
    its own, however far, does not set the yaw the gyro carries from there; two that agree to one side do."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(heading_tau=1e9, odometry_bias_span=0.0))
    Drive(d, smap).run(0.01, yaw=lambda t, x: msf_yaw, slope=slope)
    assert d.monitor.odometry.pose.yaw == pytest.approx(expected, abs=2e-4)
