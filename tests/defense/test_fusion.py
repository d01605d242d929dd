import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from testbed.defense.fusion import SafetyDrivenFusion, pose_on_lane


def test_fused_value_hand_computed():
    f = SafetyDrivenFusion(window=3, lam=1.0, q=0.05, p0=1.0)
    # Alg. 4: s_msf = 0.8, s_ld = 0.2, g = 0.4 -> R_msf = 2, R_ld = 0.5 (lam = 1)
    # MSF update: K1 = 1 / (1 + 2) = 1/3; d = 0.8/3 = 4/15; P = 2/3; predict P = 2/3 + 0.05 = 43/60
    # LD update:  K2 = (43/60) / (43/60 + 30/60) = 43/73; d = 4/15 + 43/73 (1/5 - 4/15) = 83/365
    step = f.update(0.8, 0.2, 0.1, 0.1)
    assert step.r_msf == pytest.approx(2.0)
    assert step.r_ld == pytest.approx(0.5)
    assert step.gain_msf == pytest.approx(1 / 3)
    assert step.gain_ld == pytest.approx(43 / 73)
    assert step.d == pytest.approx(83 / 365)
    # P = (43/60)(30/73) + 0.05 after the second predict
    assert f.kf.p == pytest.approx(43 / 60 * 30 / 73 + 0.05)


def test_matches_filterpy_kalman_filter():
    rng = np.random.default_rng(7)
    f = SafetyDrivenFusion(window=4, lam=0.7, q=0.03, p0=0.5)
    kf = KalmanFilter(dim_x=1, dim_z=1)
    kf.x[:] = 0.0
    kf.P[:] = 0.5
    kf.Q[:] = 0.03
    kf.F[:] = 1.0
    kf.H[:] = 1.0
    for _ in range(30):
        d_msf, d_ld = rng.normal(0.3, 0.4), rng.normal(-0.1, 0.1)
        step = f.update(d_msf, d_ld, 0.2, 0.05)
        kf.update(d_msf, R=step.r_msf)
        kf.predict()
        assert step.gain_msf == pytest.approx(kf.K[0, 0])
        kf.update(d_ld, R=step.r_ld)
        kf.predict()
        assert step.gain_ld == pytest.approx(kf.K[0, 0])
        assert step.d == pytest.approx(kf.x[0, 0])


def test_aggressive_msf_gets_smaller_gain():
    f = SafetyDrivenFusion(window=20, lam=0.8, q=0.05, p0=1.0)
    for i in range(20):
        step = f.update(0.1 * i, -0.05, 0.1, 0.1)  # MSF ramps away, LD stays near the centre
    assert step.gain_msf < 0.1 < step.gain_ld
    assert abs(step.d) < 0.3


def test_pose_on_lane_along_left_normal():
    # heading 90 deg (north): the left normal points west (-x)
    p = pose_on_lane(np.array([10.0, 5.0]), math.pi / 2, 0.4, 1.5)
    assert (p.x, p.y, p.yaw) == pytest.approx((9.6, 5.0, 1.5))
