import math

import numpy as np
import pytest

from testbed.localization.msf import MsfParams, MultiSensorFusion
from testbed.localization.sensors import GnssFix, ImuSample, LidarFix
from tracks.pose import Pose

START = Pose(0.0, 0.0, 0.0)


def driven(seconds: float = 1.0, speed: float = 10.0) -> MultiSensorFusion:
    msf = MultiSensorFusion(START, speed)
    for i in range(round(seconds * 100) + 1):
        msf.predict(ImuSample(i * 0.01, 0.0, 0.0))
    return msf


def gnss(msf: MultiSensorFusion, dy: float, std: float) -> GnssFix:
    return GnssFix(msf.t, np.array([msf.pose.x, msf.pose.y + dy]), np.eye(2) * std**2)


def test_imu_propagation_dead_reckons_and_grows_uncertainty():
    msf = driven(2.0, 10.0)
    assert msf.pose.x == pytest.approx(20.0, abs=1e-6)
    assert msf.pose.y == pytest.approx(0.0, abs=1e-9)
    p0 = MsfParams().init_pos_std ** 2
    assert msf.P[1, 1] > p0


def test_turning_imu_sample_turns_the_estimate():
    msf = MultiSensorFusion(START, 10.0)
    for i in range(101):
        msf.predict(ImuSample(i * 0.01, 0.0, 0.1))
    assert msf.pose.yaw == pytest.approx(0.1, abs=1e-9)
    assert msf.pose.y > 0.4


def test_gnss_inside_the_gate_pulls_the_estimate_by_its_reported_covariance():
    a, b = driven(), driven()
    assert a.update_gnss(gnss(a, 0.2, 0.3))
    assert b.update_gnss(gnss(b, 0.2, 1.0))
    assert 0.0 < b.pose.y < a.pose.y < 0.2


def test_gnss_outside_the_gate_is_rejected_and_leaves_the_state():
    msf = driven()
    before = msf.pose
    assert not msf.update_gnss(gnss(msf, 5.0, 0.3))
    assert msf.pose == before
    assert msf.rejected["gnss"] == 1


def test_precise_lidar_outweighs_gnss():
    a, b = driven(), driven()
    a.update_gnss(gnss(a, 0.1, 0.3))
    p = b.pose
    b.update_lidar(LidarFix(b.t, np.array([p.x, p.y + 0.1]), p.yaw, np.diag([0.04**2, 0.04**2, 1e-5])))
    assert b.pose.y > 3 * a.pose.y


def test_update_shrinks_covariance_and_estimate_exposes_it():
    msf = driven()
    before = msf.P[1, 1]
    p = msf.pose
    msf.update_lidar(LidarFix(msf.t, np.array([p.x, p.y]), p.yaw, np.diag([0.04**2, 0.04**2, 1e-5])))
    est = msf.estimate(msf.t)
    assert est.cov.shape == (3, 3)
    assert np.allclose(est.cov, est.cov.T)
    assert est.cov[1, 1] < before
    assert est.pose == msf.pose


def test_lidar_rejected_for_long_is_readmitted():
    msf = driven()
    t0 = msf.t
    readmitted = False
    for k in range(1, 60):
        t = t0 + 0.1 * k
        for j in range(1, 11):
            msf.predict(ImuSample(t - 0.1 + 0.01 * j, 0.0, 0.0))
        p = msf.pose
        ok = msf.update_lidar(LidarFix(t, np.array([p.x, 1.0]), p.yaw, np.diag([0.04**2, 0.04**2, 1e-5])))
        if ok:
            readmitted = True
            break
        assert t - t0 < MsfParams().lidar_reset_after + 0.3
    assert readmitted
    assert msf.rejected["lidar"] >= 1
    assert math.isfinite(msf.pose.y)
