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


def _stack_state(stack) -> tuple:
    imu, msf = stack.imu, stack.msf
    return (msf.nominal.tobytes(), msf.P.tobytes(), msf.t, imu.accel_bias, imu.gyro_bias, imu._last_t,
            imu._schedule._next, str(imu.rng.bit_generator.state), dict(msf.rejected))


@pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")
@pytest.mark.parametrize("control_hz", [100.0, 40.0, 20.0, 7.0])
def test_compiled_imu_propagation_equals_the_python_reference(control_hz):
    """Two stacks of one seed, one with the IMU's samples and the propagation compiled, through ticks at the
    control rate (a tick repeated now and then: no sample due), GNSS and LiDAR fixes between: the same filter
    state, IMU state, generator state and estimate after every tick."""
    from testbed.chassis import ChassisState
    from testbed.localization.stack import LocalizationConfig, LocalizationStack

    def make():
        return LocalizationStack(LocalizationConfig(), np.random.default_rng(9), lambda x, y: 0.6,
                                 Pose(3.0, -2.0, 3.1), 12.0)

    fast, slow = make(), make()
    slow._imu_step = None
    assert fast._imu_step is not None
    rng = np.random.default_rng(1)
    t = 0.0
    for k in range(1500):
        if k % 53 != 7:
            t = round(t + 1.0 / control_hz, 9)
        truth = ChassisState(t=t, speed=12.0, steer=0.0, accel=float(rng.normal(0.0, 1.0)),
                             true_pose=Pose(3.0 + 12.0 * t * math.cos(3.1), -2.0 + 12.0 * t * math.sin(3.1), 3.1),
                             yaw_rate=float(rng.normal(0.0, 0.2)))
        a, b = fast.step(t, truth), slow.step(t, truth)
        assert _stack_state(fast) == _stack_state(slow), k
        assert a.pose == b.pose and a.cov.tobytes() == b.cov.tobytes()
