import math

import numpy as np
import pytest

from testbed.defense.bicycle import BicycleCoefficients, BicycleModel
from testbed.defense.savior import SaviorConfig, SaviorDefense
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tests.defense.fake_map import FakeStraightMap
from tracks.pose import Pose

TRUE = BicycleCoefficients(wheelbase=2.8, rear_ratio=0.45, steer_gain=0.8, accel_gain=0.9, drag=0.05)
DT = 0.01


def drive(duration_s: float, rng: np.random.Generator):
    """The plant is the bicycle model with TRUE coefficients: rows t, x, y, yaw, speed, steer, accel."""
    model = BicycleModel(TRUE)
    state = np.array([0.0, 0.0, 0.0, 8.0])
    rows = []
    for k in range(round(duration_s / DT)):
        t = k * DT
        steer = 0.03 * math.sin(0.4 * t) + 0.002 * rng.standard_normal()
        accel = 0.8 * math.sin(0.25 * t)
        rows.append([t, *state, steer, accel])
        state = model.step(state, steer, accel, DT)
    return np.array(rows)


def test_fit_recovers_bicycle_coefficients():
    rng = np.random.default_rng(1)
    logs = [drive(30.0, rng) for _ in range(2)]
    for log in logs:
        log[:, 1:3] += rng.normal(0.0, 0.02, size=(len(log), 2))  # position sensor noise
    fit = SaviorDefense.fit_bicycle_coefficients(logs, wheelbase=2.8)
    assert fit.steer_gain == pytest.approx(TRUE.steer_gain, rel=0.05)
    assert fit.accel_gain == pytest.approx(TRUE.accel_gain, rel=0.05)
    assert fit.drag == pytest.approx(TRUE.drag, abs=0.01)


def test_fit_rejects_logs_shorter_than_the_horizon():
    with pytest.raises(ValueError, match="horizon"):
        SaviorDefense.fit_bicycle_coefficients([np.zeros((5, 7))], wheelbase=2.8)  # t not increasing
    short = np.zeros((5, 7))
    short[:, 0] = np.arange(5) * 0.01  # 0.04 s of log < 1 s horizon
    with pytest.raises(ValueError, match="horizon"):
        SaviorDefense.fit_bicycle_coefficients([short], wheelbase=2.8)


def run_savior(spoof_from_s: float | None, duration_s: float = 20.0):
    rng = np.random.default_rng(3)
    log = drive(duration_s, rng)
    d = SaviorDefense(SaviorConfig(savior_b=1.0, savior_tau=3.0), TRUE)
    smap = FakeStraightMap(lanes=1, width=1e6)
    cov = np.eye(2) * 0.3**2
    for k, (t, x, y, yaw, v, steer, accel) in enumerate(log):
        if k % 5 == 0:
            msf = LocalizationEstimate(t, Pose(x, y, yaw), np.eye(3) * 0.01)
            d.on_lane_detection(LaneDetection.empty(t), msf, smap)
        d.on_command(t, steer, accel, v + rng.normal(0.0, 0.05))
        if k % 10 == 0:
            fix = np.array([x, y]) + rng.normal(0.0, 0.3, size=2)
            if spoof_from_s is not None and t >= spoof_from_s:
                fix += np.array([-math.sin(yaw), math.cos(yaw)]) * 3.0  # 3 m to the left
            d.on_gnss(t, fix, cov)
    return d, log


def test_benign_drive_raises_no_alarm():
    d, _ = run_savior(spoof_from_s=None)
    assert not d.status().detected and d.mode == "normal"
    assert d.status().cusum < 3.0


def test_spoofed_gnss_is_detected_and_response_uses_the_ekf_pose():
    d, log = run_savior(spoof_from_s=10.0, duration_s=13.0)
    s = d.status()
    # residual about 3 m per fix: S grows by about 2 per fix, so > 3 at the second spoofed fix
    assert s.detected and 10.0 <= s.detection_time <= 10.25
    assert d.mode == "ar" and d.stop_decel == 4.0
    _, x, y, yaw, *_ = log[-1]
    msf = LocalizationEstimate(13.0, Pose(x - 3 * math.sin(yaw), y + 3 * math.cos(yaw), yaw), np.eye(3))
    pose = d.pose_for_control(msf, FakeStraightMap())
    # dead-reckoned for 3 s: within 1 m of the truth, unlike the 3 m spoofed MSF
    assert math.hypot(pose.x - x, pose.y - y) < 1.0


def test_bad_inputs_are_skipped():
    d = SaviorDefense(SaviorConfig())
    d.on_gnss(0.0, np.array([0.0, 0.0]), np.eye(2))  # before init: ignored
    d.on_lane_detection(
        LaneDetection.empty(0.0), LocalizationEstimate(0.0, Pose(0, 0, 0), np.eye(3)), FakeStraightMap()
    )
    d.on_command(0.01, 0.0, 0.0, math.nan)
    d.on_command(0.02, math.nan, 0.0, 1.0)
    d.on_gnss(0.1, np.array([math.nan, 0.0]), np.eye(2))
    assert d.faults.counts == {"bad-command": 2, "bad-gnss": 1}
    assert d.predicted_pose().is_finite() and d.status().cusum == 0.0
