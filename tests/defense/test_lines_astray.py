"""LD3's fail-closed vote on the lines (`lines_gate`, `lines_heading_gate`, `lines_heading_gate_in_place`): lines
apart from both the MSF and the dead-reckoned pose are astray and not compared (the MSF is checked against odometry
on that detection); lines that agree with either are compared as before, so an MSF attacker cannot have honest lines
set aside, and astray lines are no cover for an attacked MSF."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from testbed.defense.config import DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.params import ParamsError
from tests.defense.fake_map import FakeStraightMap
from tracks.pose import Pose

HALF = 1.75
SPEED = 10.0


def never(t: float) -> float:
    return 0.0


def drive(seconds: float = 4.0, *, msf_shift: Callable[[float], float] = never,
          msf_yaw: Callable[[float], float] = never, ld_shift: Callable[[float], float] = never,
          ld_slope: Callable[[float], float] = never, lines_seen: Callable[[float], bool] = lambda t: True,
          yaw_rate: Callable[[float], float] = never, **config) -> Ld3Defense:
    """A car on the centre of lane 0 of a straight road at SPEED (truly heading along it); the MSF pose `msf_shift(t)`
    m to its left with yaw `msf_yaw(t)`; the lines seen as for a car `ld_shift(t)` m left, turned by the slope
    `ld_slope(t)`, where `lines_seen(t)` (none elsewhere); odometry's yaw rate `yaw_rate(t)` (a gyro's error). Odometry
    at 100 Hz, detections at 20 Hz; `config` overrides `DefenseConfig`."""
    smap = FakeStraightMap(lanes=3)
    d = Ld3Defense(DefenseConfig(**config))
    for k in range(round(seconds * 100)):
        t = k / 100.0
        d.on_odometry(t, SPEED, yaw_rate(t))
        if k % 5:
            continue
        est = LocalizationEstimate(t, Pose(50.0 + SPEED * t, msf_shift(t), msf_yaw(t)), np.eye(3) * 0.01)
        if lines_seen(t):
            dev, slope = ld_shift(t), ld_slope(t)
            ld = LaneDetection(t, np.array([HALF - dev, slope, 0, 0.0]), np.array([-HALF - dev, slope, 0, 0.0]),
                               0.9, 0.9, (0.0, 40.0))
        else:
            ld = LaneDetection.empty(t)
        d.on_lane_detection(ld, est, smap)
        d.pose_for_control(est, smap)
    return d


def after(t0: float, value: float) -> Callable[[float], float]:
    return lambda t: value if t >= t0 else 0.0


def kinds(d: Ld3Defense) -> set[str]:
    return {r.kind for r in d.fault_records()}


def test_lines_jumped_away_from_a_true_msf_and_odometry_are_astray_and_raise_nothing():
    d = drive(ld_shift=after(1.0, 1.5))
    assert d.mode == "normal" and d.detection_time is None
    assert "lines-astray" in kinds(d)
    assert d.monitor.detector.statistic == 0.0  # the MSF was checked against odometry, which it matches
    assert abs(d.monitor.reckoned.y) < 0.05  # odometry was not moved by them either


def test_without_the_vote_the_same_lines_raise_the_alarm():
    d = drive(ld_shift=after(1.0, 1.5), lines_gate=100.0)
    assert drive(ld_shift=after(1.0, 0.9)).mode == "ar"  # within the gate of odometry: compared
    assert d.mode == "ar" and d.monitor.alarm_check == "lateral-lines" and "lines-astray" not in kinds(d)


def test_an_attacked_msf_is_still_judged_by_honest_lines():
    # the lines agree with odometry, so they are compared: the vote cannot set them aside
    d = drive(msf_shift=after(1.0, 1.0))
    assert d.mode == "ar" and d.monitor.alarm_check == "lateral-lines" and "lines-astray" not in kinds(d)


def test_astray_lines_are_no_cover_for_an_attacked_msf():
    # the lines jump away as the MSF starts a ramp: astray while the MSF keeps within b of odometry (the check where
    # lines are absent), compared again, and the alarm raised, once it does not
    d = drive(msf_shift=lambda t: max(0.0, 0.5 * (t - 1.0)), ld_shift=after(1.0, 1.5))
    assert d.mode == "ar" and "lines-astray" in kinds(d)
    assert d.detection_time < 1.0 + 0.3 / 0.5  # the MSF under 0.3 m off


def test_lines_apart_from_an_msf_and_odometry_that_disagree_are_compared():
    # no two sources agree: the lines are not set aside (here an odometry 0.9 m off, after 3 s on a gyro 0.02 rad/s
    # off without lines, and lines 1.5 m off the car: the alarm comes from the lines)
    d = drive(seconds=4.5, lines_seen=lambda t: not 1.0 <= t < 4.0, ld_shift=after(4.0, 1.5),
              yaw_rate=after(1.0, 0.02), tau=100.0, heading_tau=100.0)
    assert "lines-astray" not in kinds(d)
    steady = drive(seconds=4.5, lines_seen=lambda t: not 1.0 <= t < 4.0, ld_shift=after(4.0, 1.5), tau=100.0,
                   heading_tau=100.0)
    assert "lines-astray" in kinds(steady)  # the same lines beside an odometry that agrees with the MSF


def test_lines_turned_away_from_a_true_msf_yaw_are_astray_in_heading():
    d = drive(ld_slope=after(1.0, 0.1))
    assert d.detection_time is None and "lines-astray" in kinds(d)
    assert d.monitor.heading.statistic == 0.0
    turned = drive(ld_slope=after(1.0, 0.1), lines_heading_gate=100.0, lines_heading_gate_in_place=100.0)
    assert turned.mode == "ar" and turned.monitor.alarm_check == "heading-lines"


@pytest.mark.parametrize("slope", [0.04, -0.045])
def test_lines_turned_just_over_heading_b_where_they_agree_across_the_lane_are_astray(slope):
    """Lines a detector reads 0.04-0.045 rad turned from the start (a little over heading_b: the neural detector's in
    rain) but in place across the lane, beside a true MSF: the first anchor takes the MSF's heading (the middle of the
    three), the lines are turned from both agreeing sources beyond `lines_heading_gate_in_place` and set aside, and
    nothing alarms (with that gate at `lines_heading_gate`'s 0.05 rad they are compared and the heading check alarms).
    The same lines also 0.3 m across the lane (beyond b: a road patch that moves them) keep the wider gate, are
    compared, and raise the alarm."""
    d = drive(ld_slope=lambda t: slope)
    assert d.detection_time is None and "lines-astray" in kinds(d) and abs(d.monitor.reckoned.yaw) < 1e-6
    former = drive(ld_slope=lambda t: slope, lines_heading_gate_in_place=0.05)
    assert former.mode == "ar" and former.monitor.alarm_check == "heading-lines"
    moved = drive(ld_slope=lambda t: slope, ld_shift=lambda t: 0.3)
    assert moved.mode == "ar" and "lines-astray" not in kinds(moved)


def test_an_msf_yaw_bias_is_still_judged_by_honest_lines():
    d = drive(msf_yaw=after(1.0, 0.1))
    assert d.mode == "ar" and d.monitor.alarm_check == "heading-lines" and "lines-astray" not in kinds(d)


def test_lines_that_agree_with_the_msf_re_anchor_an_odometry_that_drifted_while_they_were_absent():
    # 3 s without lines on a gyro 0.02 rad/s off from when they went: odometry drifts about 0.9 m; the CUSUM out
    # of reach (both CUSUMs)
    gyro = {"lines_seen": lambda t: not 1.0 <= t < 4.0, "yaw_rate": after(1.0, 0.02), "tau": 100.0,
            "heading_tau": 100.0}
    drifting = drive(seconds=4.0, **gyro)
    assert drifting.monitor.reckoned.y > 0.8
    gap = drive(seconds=4.1, **gyro)
    assert gap.mode == "normal" and "lines-astray" not in kinds(gap)
    assert abs(gap.monitor.reckoned.y) < 0.1  # anchored back on the lines the MSF agrees with


def test_the_vote_is_a_fail_closed_key():
    with pytest.raises(ParamsError, match="lines_gate"):
        DefenseConfig.from_dict({"fail_closed": False, "lines_gate": 1.0})
