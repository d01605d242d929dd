"""Odometry's yaw-rate error per metre (a steering-angle offset in a yaw rate derived as v tan δ / L) is learnt
from the MSF's yaw where MSF and lines agree, and every odometry-carried pose moves on the corrected rate.
Without it a chassis that reports no yaw rate drifts its dead-reckoned yaw, and the steered yaw with it, while
both sources agree the car is centred; an attacker who turns either source within the agreement teaches it next
to nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from testbed.defense.config import DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.odometry import MAX_CURVATURE, CurvatureBias
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tests.defense.fake_map import FakeStraightMap
from tracks.pose import Pose, wrap_angle

HALF = 1.75
OFFSET_1DEG = math.tan(math.radians(1.0)) / 2.8
"""A 1° steering-angle offset on a 2.8-m wheelbase, as a yaw-rate error per metre (rad/m)."""


def learn(kappa: float, seconds: float, heading_error=lambda t: 0.0, noise: float = 0.0, span: float = 100.0,
          speed=lambda t: 4.0 + 3.0 * math.sin(0.3 * t), turn=lambda t: 0.2 * math.sin(0.5 * t)) -> CurvatureBias:
    """Odometry at 100 Hz reporting the true yaw rate `turn(t)` plus `kappa`·v; an independent heading (true plus
    `heading_error(t)` and Gaussian `noise`) observed at 20 Hz."""
    bias, rng = CurvatureBias(span), np.random.default_rng(7)
    yaw = 0.0
    for k in range(round(seconds * 100)):
        t = k / 100
        v, w = speed(t), turn(t)
        if k:
            yaw += 0.5 * (w + turn(t - 0.01)) * 0.01
        bias.on_odometry(t, v, w + kappa * v)
        if k % 5 == 0:
            bias.observe(wrap_angle(yaw + heading_error(t) + noise * rng.normal()))
    return bias


@pytest.mark.parametrize("kappa", [OFFSET_1DEG, -0.5 * OFFSET_1DEG, 0.0])
def test_a_steering_offset_is_learnt_per_metre_at_any_speed_and_taken_out(kappa):
    bias = learn(kappa, 30.0, noise=0.003)
    assert bias.curvature == pytest.approx(kappa, abs=3e-4)
    assert bias.corrected(6.0, 0.1 + kappa * 6.0) == pytest.approx(0.1, abs=6.0 * 3e-4)


def test_headings_across_the_wrap_of_whole_circles_give_the_same_estimate():
    bias = learn(OFFSET_1DEG, 60.0, turn=lambda t: 0.6, speed=lambda t: 5.0)  # 5.7 turns
    assert bias.curvature == pytest.approx(OFFSET_1DEG, abs=1e-6)


def test_a_constant_heading_error_teaches_no_bias():
    """Lines read rotated by a fixed angle inside the agreement: a gap that does not grow with distance."""
    assert abs(learn(0.0, 30.0, heading_error=lambda t: 0.009).curvature) < 1e-9


def test_no_estimate_before_the_samples_spread_nor_with_no_span_and_never_beyond_the_cap():
    assert learn(OFFSET_1DEG, 1.0, speed=lambda t: 2.0).curvature == 0.0  # 2 m driven
    assert learn(OFFSET_1DEG, 30.0, span=0.0).curvature == 0.0
    assert learn(0.1, 30.0).curvature == MAX_CURVATURE
    assert learn(-0.1, 30.0).curvature == -MAX_CURVATURE


def centred_lines(t: float, psi: float = 0.0) -> LaneDetection:
    """Lines of a centred car read turned by `psi` (rad, + left)."""
    c1 = -math.tan(psi)
    return LaneDetection(t, np.array([HALF, c1, 0, 0.0]), np.array([-HALF, c1, 0, 0.0]), 0.9, 0.9, (0.0, 40.0))


def drive_straight(seconds: float, speed: float, kappa: float, psi=lambda t: 0.0, msf_yaw=lambda t: 0.0,
                   **config) -> tuple[Ld3Defense, list[float], list[float]]:
    """A car centred in its lane heading +x; odometry at 40 Hz reports `kappa`·v as its yaw rate (true: 0); the
    MSF pose is true but for its yaw `msf_yaw(t)`, and the lines are read turned by `psi(t)`, at 20 Hz. The
    dead-reckoned yaw and the steered yaw on every tick while normal."""
    smap, d = FakeStraightMap(), Ld3Defense(DefenseConfig(**config))
    reckoned, steered = [], []
    for k in range(round(seconds * 40)):
        t = k / 40
        d.on_odometry(t, speed, kappa * speed)
        est = LocalizationEstimate(t, Pose(50.0 + speed * t, 0.0, msf_yaw(t)), np.eye(3) * 0.01)
        if k % 2 == 0:
            d.on_lane_detection(centred_lines(t, psi(t)), est, smap)
        pose = d.pose_for_control(est, smap)
        if d.mode != "ar" and d.monitor.reckoned is not None:
            reckoned.append(d.monitor.reckoned.yaw)
            steered.append(pose.yaw)
    return d, reckoned, steered


def test_a_steering_offset_does_not_turn_the_steered_yaw_of_a_centred_car():
    d, reckoned, steered = drive_straight(30.0, 4.0, OFFSET_1DEG)
    assert not d.status().detected
    assert d.monitor.yaw_bias.curvature == pytest.approx(OFFSET_1DEG, abs=1e-4)
    assert max(map(abs, reckoned)) < OFFSET_1DEG * 7.0  # the 6 m before MIN_LEVERAGE, then removed
    assert abs(reckoned[-1]) < 1e-3 and abs(steered[-1]) < 1e-3
    assert max(map(abs, steered)) < max(map(abs, reckoned)) - DefenseConfig().steer_yaw_tol + 1e-3  # the clamp


def test_without_the_estimate_the_offset_steers_a_centred_car_and_nothing_alarms():
    d, reckoned, steered = drive_straight(10.0, 4.0, OFFSET_1DEG, odometry_bias_span=0.0)
    assert not d.status().detected
    assert reckoned[-1] > 0.2 and steered[-1] > 0.19  # 0.25 rad of drift less line_yaw_rate's 0.02


def test_lines_rotated_inside_the_agreement_teach_nothing_and_do_not_steer():
    """A road patch that turns the lines to 0.009 rad over 10 s and holds them there (the MSF true): under the
    agreement with the MSF's heading, so it is learnt from all along."""
    d, _, steered = drive_straight(30.0, 20.0, 0.0, psi=lambda t: 0.009 * min(1.0, t / 10.0))
    assert not d.status().detected
    assert abs(d.monitor.yaw_bias.curvature) < 1e-9
    assert max(map(abs, steered)) < 1e-9  # the MSF's true yaw


def test_an_msf_yaw_turned_inside_the_agreement_teaches_next_to_nothing():
    """An MSF attacker who turns its yaw to 0.009 rad over 10 s (the lines true): learnt all along, a slope of
    0.009 rad over 200 m at most; the steered yaw stays within the agreement, as the clamp alone allows."""
    d, reckoned, steered = drive_straight(30.0, 20.0, 0.0, msf_yaw=lambda t: 0.009 * min(1.0, t / 10.0))
    assert not d.status().detected
    assert abs(d.monitor.yaw_bias.curvature) < 0.009 / 200.0
    assert max(map(abs, reckoned)) < 0.005 and max(map(abs, steered)) < 0.0091  # the MSF's, carried between


def test_the_first_estimate_owes_the_carried_yaw_what_its_bias_turned_it_by_and_then_nothing():
    bias = CurvatureBias(100.0)
    owed, k = [], 0
    while not bias.estimated:
        t = k / 100
        bias.on_odometry(t, 5.0, 5.0 * OFFSET_1DEG)  # the true yaw rate is 0
        if k % 5 == 0:
            owed.append(bias.observe(0.0))
        k += 1
    driven = 5.0 * (k - 1) / 100
    assert owed[:-1] == [0.0] * (len(owed) - 1)
    assert owed[-1] == pytest.approx(-OFFSET_1DEG * driven, rel=1e-6)
    bias.on_odometry(k / 100, 5.0, 5.0 * OFFSET_1DEG)
    assert bias.observe(0.0) == 0.0


def test_the_defense_hands_the_loop_the_corrected_yaw_rate_and_the_paper_mode_the_reported_one():
    d, _, _ = drive_straight(20.0, 4.0, OFFSET_1DEG)
    deadband = 0.5 * DefenseConfig().line_yaw_rate  # left to the lines' turn of the yaw
    assert d.odometry_yaw_rate(4.0, 0.3) == pytest.approx(0.3 - (4.0 * OFFSET_1DEG - deadband), abs=4e-4)
    assert d.odometry_bias() == pytest.approx(OFFSET_1DEG, abs=1e-4)
    paper, _, _ = drive_straight(20.0, 4.0, OFFSET_1DEG, fail_closed=False)
    assert paper.odometry_yaw_rate(4.0, 0.3) == 0.3 and paper.odometry_bias() is None


def test_a_bias_under_the_deadband_is_left_to_the_lines_and_the_rest_taken_out():
    bias = learn(1e-4, 30.0, speed=lambda t: 5.0)
    bias.deadband = 0.001
    assert bias.curvature == pytest.approx(1e-4, abs=1e-6)
    assert bias.corrected(5.0, 0.2) == 0.2  # 0.0005 rad/s: the lines' turn takes it out
    assert bias.corrected(30.0, 0.2) == pytest.approx(0.2 - (30.0 * 1e-4 - 0.001))
    assert bias.correction(-30.0) == pytest.approx(-(30.0 * 1e-4 - 0.001))  # reversing: the sign follows v
