"""Offline CUSUM sweeps (testbed.defense.roc) and the passive recorder they read (testbed.defense.recorder)."""

import math

import numpy as np
import pytest

from testbed.defense.attack_detection import cusum_alarm_index
from testbed.defense.bicycle import BicycleCoefficients, BicycleModel
from testbed.defense.recorder import DetectionRecorder, load_detection_log
from testbed.defense.roc import (
    ResidualSeries,
    RocPoint,
    cusum_running_max,
    first_alarm_times,
    ld3_series,
    replay_savior,
    roc_auc,
    roc_frontier,
    roc_sweep,
)
from testbed.defense.savior import SaviorConfig, SaviorDefense
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tests.defense.fake_map import FakeStraightMap
from tracks.pose import Pose

HALF = 1.75


def series(r, start=None, segment=None, dt=0.05):
    r = np.asarray(r, dtype=float)
    seg = np.zeros(len(r), dtype=int) if segment is None else np.asarray(segment)
    return ResidualSeries(np.arange(len(r)) * dt, r, seg, start)


def test_running_max_by_hand():
    # b = 0.6: S = 0, 0.3, 0, 0.4 -> M = 0, 0.3, 0.3, 0.4
    m = cusum_running_max(np.array([0.5, -0.9, 0.2, 1.0]), np.zeros(4, dtype=int), 0.6)
    assert m == pytest.approx([0.0, 0.3, 0.3, 0.4])


def test_running_max_restarts_s_at_a_new_segment():
    # b = 0.5: S = 0.5, 1.0 | reset | 0.5, 1.0; the running max keeps 1.0
    m = cusum_running_max(np.ones(4), np.array([0, 0, 1, 1]), 0.5)
    assert m == pytest.approx([0.5, 1.0, 1.0, 1.0])
    alarm = first_alarm_times(series(np.ones(4), segment=[0, 0, 1, 1]), 0.5, np.array([0.7, 1.0]))
    assert alarm[0] == pytest.approx(0.05)  # S = 1.0 > 0.7 at the 2nd residual
    assert math.isnan(alarm[1])  # S never exceeds 1.0 because of the reset


def test_first_alarm_times_agree_with_the_latched_cusum_for_every_tau():
    rng = np.random.default_rng(7)
    r = np.abs(rng.normal(0.3, 0.4, 400))
    taus = np.array([0.0, 0.05, 0.1, 0.5, 1.0, 3.0, 10.0, 1e6])
    for b in (0.0, 0.3, 0.6, 1.0):
        times = first_alarm_times(series(r), b, taus)
        for tau, t in zip(taus, times, strict=True):
            idx = cusum_alarm_index(r, b, tau)
            assert (math.isnan(t) and idx is None) or t == pytest.approx(idx * 0.05)


def test_sweep_counts_alarms_before_the_attack_as_no_detection():
    quiet = series([0.1] * 20)
    noisy = series([0.1] * 5 + [0.9] * 15)  # benign but alarms at b = 0.6
    attacked = series([0.1] * 10 + [2.0] * 10, start=0.5)  # attack from t = 0.5 (index 10)
    early = series([2.0] * 20, start=0.5)  # alarms at t = 0, before its attack
    points = roc_sweep([quiet, noisy, attacked, early], bs=[0.6, 1.0], taus=[0.1])
    assert points == [RocPoint(0.6, 0.1, 0.5, 0.5), RocPoint(1.0, 0.1, 0.0, 0.5)]


def test_sweep_needs_both_kinds_of_run():
    with pytest.raises(ValueError, match="benign and attacked"):
        roc_sweep([series([0.1])], [0.6], [0.1])


def test_frontier_and_auc_of_a_staircase():
    points = [RocPoint(0, 0, 0.0, 0.6), RocPoint(0, 1, 0.5, 0.5), RocPoint(0, 2, 0.5, 0.9), RocPoint(0, 3, 0.2, 0.8)]
    curve = roc_frontier(points)
    assert curve == [(0.0, 0.0), (0.0, 0.6), (0.2, 0.8), (0.5, 0.9), (1.0, 0.9)]
    assert roc_auc(curve) == pytest.approx(0.2 * 0.6 + 0.3 * 0.8 + 0.5 * 0.9)


def lane_det(t, phys_dev):
    return LaneDetection(t, np.array([HALF - phys_dev, 0, 0, 0.0]), np.array([-HALF - phys_dev, 0, 0, 0.0]),
                         0.9, 0.9, (0.0, 40.0))


def test_recorder_logs_the_residuals_ld3_feeds_its_cusum_and_never_responds(tmp_path):
    smap = FakeStraightMap(intersections=((100.0, 120.0),))
    rec = DetectionRecorder()
    # (x, MSF y, physical deviation): the 3rd is inside the intersection (skipped), the 4th restarts S
    for i, (x, y, phys) in enumerate([(80.0, 2.0, 0.0), (90.0, 0.5, -0.2), (110.0, 0.3, 0.0), (130.0, 0.1, 0.1)]):
        msf = LocalizationEstimate(0.05 * i, Pose(x, y, 0.0), np.eye(3) * 0.01)
        rec.on_lane_detection(lane_det(0.05 * i, phys), msf, smap)
        assert rec.mode == "normal" and rec.stop_decel is None and rec.pose_for_control(msf, smap) == msf.pose
    assert not rec.status().detected
    rec.log.save(tmp_path / "log.npz")
    rows = load_detection_log(tmp_path / "log.npz")["ld3"]
    # lane 0 (y = 2.0 is nearer lane 1's centre at 3.5: D_MSF = -1.5)
    np.testing.assert_allclose(rows, [[0.0, -1.5, 0.0, 0], [0.05, 0.5, -0.2, 0], [0.15, 0.1, 0.1, 1]], atol=1e-12)
    s = ld3_series(rows, None)
    assert s.r == pytest.approx([-1.5, 0.7, 0.0])


def drive(rng, duration_s=12.0, dt=0.01, spoof_from=None):
    """Bicycle-model plant; yields the loop's per-tick calls: (t, gnss fix or None, state, steer, accel)."""
    model = BicycleModel(BicycleCoefficients(wheelbase=2.8, rear_ratio=0.45, steer_gain=0.8))
    state = np.array([0.0, 0.0, 0.0, 8.0])
    for k in range(round(duration_s / dt)):
        t = k * dt
        steer, accel = 0.03 * math.sin(0.4 * t), 0.5 * math.sin(0.3 * t)
        fix = None
        if k % 10 == 0:
            fix = state[:2] + rng.normal(0.0, 0.3, 2)
            if spoof_from is not None and t >= spoof_from:
                fix = fix + np.array([0.0, 2.0])
        yield t, fix, state.copy(), steer, accel
        state = model.step(state, steer, accel, dt)


def test_savior_replay_reproduces_the_live_residuals():
    coeffs = BicycleCoefficients(wheelbase=2.8, rear_ratio=0.45, steer_gain=0.8)
    config = SaviorConfig(savior_tau=1e9)
    live = SaviorDefense(config, coeffs)
    rec = DetectionRecorder()
    smap = FakeStraightMap(lanes=1, width=1e6)
    live_residuals = []
    for t, fix, (x, y, yaw, v), steer, accel in drive(np.random.default_rng(2), spoof_from=6.0):
        cov = np.eye(2) * 0.09
        if fix is not None:
            for d in (live, rec):
                d.on_gnss(t, fix, cov)
            if live.ekf is not None:
                live_residuals.append((t, live.last_residual))
        if round(t / 0.01) % 5 == 0:
            msf = LocalizationEstimate(t, Pose(x, y, yaw), np.diag([0.01, 0.01, 0.001]))
            for d in (live, rec):
                d.on_lane_detection(LaneDetection.empty(t), msf, smap)
        for d in (live, rec):
            d.on_command(t, steer, accel, v)
    arrays = rec.log.arrays()
    replay = replay_savior(arrays, coeffs, 6.0, config)
    assert len(replay.r) == len(live_residuals) > 100
    assert replay.t.tolist() == pytest.approx([t for t, _ in live_residuals])
    assert replay.r.tolist() == pytest.approx([r for _, r in live_residuals], abs=1e-12)
    # the spoofed 2 m jump shows in SAVIOR's first spoofed residual (it then fuses the spoofed fixes)
    assert replay.r[replay.t >= 6.0][0] > 1.5 > 0.6 > np.median(replay.r[replay.t < 6.0])
