"""The compiled MSF propagation leaves the nominal state and the covariance as the pure-Python `predict` does,
to the bit, through IMU samples that wrap the yaw and GNSS and LiDAR updates between them; the compiled gated
update equals the reference update to rounding and makes the same gate decisions."""

import math

import numpy as np
import pytest
from scipy.stats import chi2

from testbed.localization.msf import MultiSensorFusion, observed_prefix_update
from testbed.localization.sensors import GnssFix, ImuSample, LidarFix
from tests.localization.test_msf_equations import drive_filter
from tracks.compiled import compiled_module
from tracks.pose import Pose, wrap_angle

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


ROUNDING = 1e-12
"""The compiled update against the reference, relative (measured: within 3e-15 on these cases)."""


@pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")
def test_compiled_gated_update_equals_the_reference_to_rounding():
    """4,000 random covariances over five decades, innovations over three and a half, diagonal and full noise
    covariances: the distance, the covariance and the nominal state within ROUNDING of the reference's, and
    the same gate decision at the filter's gate, also for each innovation scaled to 1e-10 inside and outside it."""
    rng = np.random.default_rng(5)
    gates = {n: float(chi2.ppf(0.999, n)) for n in (2, 3)}
    decisions = {True: 0, False: 0}
    for case in range(4000):
        n = 2 + case % 2
        a, b = rng.normal(size=(7, 7)), rng.normal(size=(n, n))
        p = (a @ a.T + 0.1 * np.eye(7)) * rng.uniform(1e-4, 10.0)
        z = rng.normal(size=n) * 10.0 ** rng.uniform(-2.0, 1.5)
        r = np.diag(rng.uniform(0.01, 1.0, n)) if case % 4 < 2 else b @ b.T + 0.01 * np.eye(n)
        s = p[:n, :n] + r
        d2 = float(z @ np.linalg.solve(s, z))
        dx, updated = observed_prefix_update(p, z, r, s)
        nominal = rng.normal(size=7) * 100.0
        expected = nominal + dx
        expected[2] = wrap_angle(expected[2])
        update = KERNELS.GatedUpdate(nominal, p)
        distance = update.distance(z, r)
        assert abs(distance - d2) <= ROUNDING * d2
        assert (distance > gates[n]) == (d2 > gates[n])
        decisions[d2 > gates[n]] += 1
        for margin in (1.0 - 1e-10, 1.0 + 1e-10):
            edge = z * math.sqrt(margin * gates[n] / d2)
            assert (update.distance(edge, r) > gates[n]) == (float(edge @ np.linalg.solve(s, edge)) > gates[n])
        update.distance(z, r)
        update.apply()
        assert np.max(np.abs(p - updated)) <= ROUNDING * np.max(np.abs(updated))
        assert np.max(np.abs(nominal - expected)) <= ROUNDING * np.max(np.abs(dx)) + np.spacing(1000.0)
    assert min(decisions.values()) > 300  # both sides of the gate


@pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")
@pytest.mark.parametrize("seed", [0, 1])
def test_compiled_filter_drives_as_the_reference(seed: int):
    """The 3,000-sample drive of `test_msf_equations` (fixes gated out for 600 samples, the LiDAR re-admitted):
    the same rejections after every step, the state and covariance within ROUNDING (no drift)."""
    start = Pose(3.0, 1.0, math.pi - 0.05)
    compiled, reference = MultiSensorFusion(start, 15.0), MultiSensorFusion(start, 15.0)
    assert compiled._gated is not None
    reference._gated = reference._updates = None
    ours, theirs = drive_filter(compiled, seed), drive_filter(reference, seed)
    assert theirs[-1][2]["gnss"] > 0 and theirs[-1][2]["lidar"] > 0
    for (x, p, rej), (x_ref, p_ref, rej_ref) in zip(ours, theirs, strict=True):
        assert rej == rej_ref
        assert np.max(np.abs(x - x_ref) / np.maximum(np.abs(x_ref), 1.0)) <= ROUNDING
        assert np.max(np.abs(p - p_ref)) <= ROUNDING * np.max(np.abs(p_ref))


@pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")
def test_compiled_gated_update_keeps_the_reference_errors():
    update = KERNELS.GatedUpdate(np.zeros(7), np.zeros((7, 7)))
    with pytest.raises(RuntimeError):
        update.apply()  # nothing measured yet
    with pytest.raises(np.linalg.LinAlgError):
        update.distance(np.array([1.0, 2.0]), np.zeros((2, 2)))  # a singular S
    with pytest.raises(np.linalg.LinAlgError):
        update.distance(np.array([1.0, 2.0, 0.0]), np.zeros((3, 3)))
    with pytest.raises(ValueError):
        update.distance(np.array([1.0, 2.0]), np.eye(3))
    assert math.isnan(KERNELS.GatedUpdate(np.zeros(7), np.eye(7)).distance(np.array([math.nan, 0.0]), np.eye(2)))
