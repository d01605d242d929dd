"""LD3 (fail-closed) steers only on checked poses: the MSF pose of the last detection update carried by odometry.
An attacker who moves the MSF pose only between detections reaches no control pose, at any control rate and
with late, dropped or irregular frames; the paper mode steers on every MSF pose and is moved."""

from __future__ import annotations

import math

import numpy as np
import pytest

from testbed.defense.alarmed import Ld3AlarmedDefense
from testbed.defense.config import DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.naive_ar import NaiveArDefense
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tests.defense.fake_map import FakeStraightMap
from tracks.pose import Pose

HALF = 1.75
SPEED = 20.0


def lines(t: float, dev: float) -> LaneDetection:
    return LaneDetection(t, np.array([HALF - dev, 0, 0, 0.0]), np.array([-HALF - dev, 0, 0, 0.0]), 0.9, 0.9,
                         (0.0, 40.0))


def frame_times(seconds: float, seed: int) -> list[float]:
    """Camera frames about every 50 ms, each late by up to 40 ms, one in six dropped, a 0.4 s stall."""
    rng = np.random.default_rng(seed)
    times, t = [], 0.0
    while t < seconds:
        if rng.random() > 1 / 6 and not 3.0 <= t < 3.4:
            times.append(t + rng.uniform(0.0, 0.04))
        t += 0.05
    return sorted(times)


def drive(defense: Ld3AlarmedDefense, control_hz: float, frames: list[float], seconds: float = 6.0,
          shift: float = 2.0, yaw: float = 0.2) -> tuple[list[Pose], list[float]]:
    """Control ticks at `control_hz`; a detection on the first tick at or after each frame time (late frames
    are processed late); between detections the MSF pose is moved `shift` m left and its yaw by `yaw`."""
    smap = FakeStraightMap()
    control, errors = [], []
    pending = list(frames)
    for k in range(round(seconds * control_hz)):
        t = round(k / control_hz, 9)
        x = 50.0 + SPEED * t
        defense.on_odometry(t, SPEED, 0.0)
        due = bool(pending) and pending[0] <= t + 1e-9
        while pending and pending[0] <= t + 1e-9:
            pending.pop(0)
        moved = not due and t >= 0.5
        pose = Pose(x, shift if moved else 0.0, yaw if moved else 0.0)
        est = LocalizationEstimate(t, pose, np.eye(3) * 0.01)
        if due:
            defense.on_lane_detection(lines(t, 0.0), est, smap)
        p = defense.pose_for_control(est, smap)
        control.append(p)
        errors.append(max(abs(p.y), abs(p.yaw), abs(p.x - x)))
    return control, errors


@pytest.mark.parametrize("control_hz", [40.0, 50.0, 100.0])
@pytest.mark.parametrize("make", [Ld3Defense, NaiveArDefense])
def test_moves_between_detections_reach_no_control_pose(control_hz, make):
    defense = make(DefenseConfig())
    _, errors = drive(defense, control_hz, frame_times(6.0, seed=int(control_hz)))
    assert max(errors) < 1e-9
    assert defense.mode == "normal" and defense.status().cusum == 0.0


@pytest.mark.parametrize("control_hz", [40.0, 100.0])
def test_the_paper_mode_steers_on_every_msf_pose_and_is_moved(control_hz):
    defense = Ld3Defense(DefenseConfig(b=0.6, tau=0.1, heading="msf", window=20, fail_closed=False))
    _, errors = drive(defense, control_hz, frame_times(6.0, seed=1))
    assert max(errors) == pytest.approx(2.0)
    assert defense.mode == "normal"


def test_a_shift_on_detection_ticks_is_what_the_check_sees_and_alarms():
    defense = Ld3Defense(DefenseConfig())
    smap = FakeStraightMap()
    for k in range(240):
        t = k / 40.0
        defense.on_odometry(t, SPEED, 0.0)
        est = LocalizationEstimate(t, Pose(50.0 + SPEED * t, 1.0 if t >= 1.0 else 0.0, 0.0), np.eye(3) * 0.01)
        if k % 2 == 0:
            defense.on_lane_detection(lines(t, 0.0), est, smap)
        defense.pose_for_control(est, smap)
    assert defense.mode == "ar"
    assert defense.detection_time == pytest.approx(1.0 + 0.05 * 2, abs=0.06)


def steered_on_detections(defense: Ld3AlarmedDefense, msf_pose) -> list[tuple[float, float, Pose, Pose]]:
    """3 s at 40 Hz on the straight with the lines centred and the MSF pose at `msf_pose(t, x)` (x the car's), a
    detection every second tick; per detection update (t, the car's x, the MSF pose, the pose steered on)."""
    smap = FakeStraightMap()
    out = []
    for k in range(120):
        t = k / 40.0
        x = 50.0 + SPEED * t
        defense.on_odometry(t, SPEED, 0.0)
        est = LocalizationEstimate(t, msf_pose(t, x), np.eye(3) * 0.01)
        if k % 2 == 0:
            defense.on_lane_detection(lines(t, 0.0), est, smap)
        pose = defense.pose_for_control(est, smap)
        if k % 2 == 0:
            out.append((t, x, est.pose, pose))
    return out


@pytest.mark.parametrize(("across", "along"), [(1.3, 0.0), (-1.3, -8.6)])
def test_until_the_alarm_a_jump_of_the_msf_moves_the_steered_pose_no_faster_than_the_slew(across, along):
    """From 1 s the MSF pose jumps `across` the lane and `along` it (the lines and odometry stay with the car): while
    normal, the pose steered on moves away from the car by `steer_slew` × 0.05 s a detection update at most, in each
    direction, and a fault says it was held."""
    config = DefenseConfig(tau=1e9, heading_tau=1e9, along_tau=1e9)
    defense = Ld3Defense(config)
    jumped = steered_on_detections(defense, lambda t, x: Pose(x + along, across, 0.0) if t >= 1.0
                                   else Pose(x, 0.0, 0.0))
    offsets = [(pose.x - x, pose.y) for t, x, _, pose in jumped if t >= 1.0]
    assert defense.mode == "normal"
    for n, (got_along, got_across) in enumerate(offsets, start=1):
        reach = config.steer_slew * 0.05 * n
        assert got_across == pytest.approx(math.copysign(min(reach, abs(across)), across), abs=1e-6)
        assert got_along == pytest.approx(math.copysign(min(reach, abs(along)), along), abs=1e-6)
    assert any(r.kind == "steer-held" for r in defense.fault_records())


def test_a_drift_of_the_msf_slower_than_the_slew_is_steered_on_as_it_is():
    """An MSF pose drifting 0.3 m/s across the lane (under `steer_slew`, 0.5 m/s), as a source dragged slowly does: the
    pose steered on is the MSF's, never held."""
    defense = Ld3Defense(DefenseConfig(tau=1e9, heading_tau=1e9, along_tau=1e9))
    updates = steered_on_detections(defense, lambda t, x: Pose(x, 0.3 * max(0.0, t - 1.0), 0.0))
    for _, x, msf, pose in updates:
        assert pose.y == pytest.approx(msf.y, abs=1e-9) and pose.x == pytest.approx(x, abs=1e-9)
    assert not any(r.kind == "steer-held" for r in defense.fault_records())


def test_an_unplaceable_msf_pose_is_not_taken_and_the_last_checked_pose_is_carried():
    defense = Ld3Defense(DefenseConfig(tau=1e9))
    smap = FakeStraightMap()
    poses = []
    for k in range(80):
        t = k / 40.0
        x = 50.0 + SPEED * t
        defense.on_odometry(t, SPEED, 0.0)
        est = LocalizationEstimate(t, Pose(x, 40.0 if t >= 1.0 else 0.0, 0.0), np.eye(3) * 0.01)
        if k % 2 == 0:
            defense.on_lane_detection(lines(t, 0.0), est, smap)
        poses.append((x, defense.pose_for_control(est, smap)))
    assert all(abs(p.y) < 1e-9 and abs(p.x - x) < 1e-9 for x, p in poses)
    assert "unchecked-msf" in {r.kind for r in defense.fault_records()}


def test_before_any_detection_the_msf_pose_is_used_and_named_a_fault():
    defense = Ld3Defense(DefenseConfig())
    est = LocalizationEstimate(0.0, Pose(1.0, 2.0, 0.1), np.eye(3) * 0.01)
    assert defense.pose_for_control(est, FakeStraightMap()) == est.pose
    assert [r.kind for r in defense.fault_records()] == ["unchecked-msf"]


def along_drive(shift_rate: float, seconds: float = 12.0) -> Ld3Defense:
    """A car at SPEED on lane 0; from t = 2 s the MSF pose slides ahead along the lane at `shift_rate` m/s, its
    lateral offset and heading true; lines every other tick."""
    defense = Ld3Defense(DefenseConfig())
    smap = FakeStraightMap()
    for k in range(round(seconds * 40)):
        t = k / 40.0
        defense.on_odometry(t, SPEED, 0.0)
        along = max(0.0, t - 2.0) * shift_rate
        est = LocalizationEstimate(t, Pose(50.0 + SPEED * t + along, 0.0, 0.0), np.eye(3) * 0.01)
        if k % 2 == 0:
            defense.on_lane_detection(lines(t, 0.0), est, smap)
        defense.pose_for_control(est, smap)
    return defense


def test_an_msf_pose_sliding_along_the_lane_is_caught_by_the_along_check():
    fast = along_drive(5.0)
    assert fast.mode == "ar" and fast.monitor.along.alarmed and not fast.monitor.detector.alarmed
    assert fast.status().alarm_check == "along-odometry"
    # caught within a few metres: weight 0.5 m, threshold 2 m, the dead-reckoned station taking 5 % an anchor
    assert fast.detection_time < 2.0 + 3.0 / 5.0


def test_a_drift_below_the_along_check_s_rate_stays_undetected_and_the_station_lags_it():
    slow = along_drive(0.2)  # under 0.5 m × 0.05 × 20 Hz = 0.5 m/s
    assert slow.mode == "normal" and slow.monitor.along.statistic == 0.0
    reckoned = slow.monitor.reckoned
    true_x = 50.0 + SPEED * (479 / 40.0)
    # the dead-reckoned station lags the 2 m the MSF slid by the steady gap rate / (gain × rate) = 0.2 m
    assert reckoned.x - true_x == pytest.approx(2.0 - 0.2, abs=0.1)


def test_the_paper_mode_runs_no_along_check():
    with pytest.raises(ValueError, match="along_b"):
        DefenseConfig(fail_closed=False, along_b=1.0)


def rotated_lines(t: float, psi: float) -> LaneDetection:
    """Lines of a centred car that the detector reads rotated by `psi` (rad, + left): slope c1 = −tan ψ."""
    c1 = -np.tan(psi)
    return LaneDetection(t, np.array([HALF, c1, 0, 0.0]), np.array([-HALF, c1, 0, 0.0]), 0.9, 0.9, (0.0, 40.0))


def steer_on_rotated_lines(cap: float = math.inf, **config) -> list[float]:
    """A centred car with a true MSF pose (yaw 0); from 1 s the lines are read turned left at 0.1 rad/s up to `cap`
    (a road patch's bend, under the heading check's weight for 0.3 s); the yaws of the control poses while normal."""
    smap = FakeStraightMap()
    d = Ld3Defense(DefenseConfig(**config))
    yaws = []
    for k in range(3 * 40):
        t = k / 40.0
        d.on_odometry(t, SPEED, 0.0)
        est = LocalizationEstimate(t, Pose(50.0 + SPEED * t, 0.0, 0.0), np.eye(3) * 0.01)
        if k % 2 == 0:
            d.on_lane_detection(rotated_lines(t, min(cap, 0.1 * max(0.0, t - 1.0))), est, smap)
        pose = d.pose_for_control(est, smap)
        if d.mode != "ar":
            yaws.append(pose.yaw)
    return yaws


def test_lines_rotated_by_a_road_patch_turn_the_steered_yaw_no_faster_than_the_gyro_drifts():
    yaws = steer_on_rotated_lines()
    config = DefenseConfig()
    assert len(yaws) > 60  # normal for at least 1.5 s
    assert max(abs(y) for y in yaws) <= config.steer_yaw_tol + config.line_yaw_rate * 2.0 + 1e-9


def test_even_without_the_rate_lines_rotated_within_the_heading_check_leave_the_steered_yaw_to_the_gyro():
    # lines bent slowly under the heading check (0.025 of its 0.03 rad) beside a true MSF: the dead-reckoned yaw, on
    # the true 0 inside the interval between the MSF's heading and the lines', is not turned at any rate
    yaws = steer_on_rotated_lines(cap=0.025, line_yaw_rate=1e9)
    assert max(abs(y) for y in yaws) <= 1e-9


def test_lines_rotated_past_the_heading_check_turn_the_steered_yaw_no_further_even_without_the_rate():
    yaws = steer_on_rotated_lines(line_yaw_rate=1e9)
    config = DefenseConfig()
    assert max(abs(y) for y in yaws) <= config.heading_b + config.steer_yaw_tol + 1e-9
