"""The compiled MSF propagation leaves the nominal state and the covariance as the pure-Python `predict` does,
to the bit, through IMU samples that wrap the yaw and GNSS and LiDAR updates between them."""

import math

import numpy as np
import pytest

from testbed.localization.msf import MultiSensorFusion
from testbed.localization.sensors import GnssFix, ImuSample, LidarFix
from tracks.compiled import compiled_module
from tracks.pose import Pose

KERNELS = compiled_module("testbed.localization.msf_kernels")


@pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")
def test_compiled_predict_equals_the_python_reference():
    start = Pose(12.0, -4.0, math.pi - 0.01)  # the yaw wraps through ±π on the way
    compiled, pure = MultiSensorFusion(start, 20.0), MultiSensorFusion(start, 20.0)
    pure._predictor = None
    assert compiled._predictor is not None
    rng = np.random.default_rng(4)
    t = 0.0
    for k in range(3000):
        t += 0.01 * rng.uniform(0.5, 1.5)
        imu = ImuSample(t, float(rng.normal(0.0, 1.0)), float(rng.normal(0.05, 0.2)))
        for msf in (compiled, pure):
            msf.predict(imu)
            if k % 10 == 3:
                msf.update_gnss(GnssFix(t, msf.nominal[:2] + np.array([0.3, -0.2]), np.eye(2) * 0.16))
            if k % 10 == 7:
                msf.update_lidar(LidarFix(t, msf.nominal[:2] + np.array([-0.05, 0.04]), float(msf.nominal[2]) + 0.01,
                                          np.diag([0.01, 0.01, 1e-4])))
        assert np.array_equal(compiled.nominal, pure.nominal) and np.array_equal(compiled.P, pure.P)
