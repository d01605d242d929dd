"""The MSF's covariance propagation and measurement update against filterpy's KalmanFilter, bit for bit, and the
filter's update on preallocated arrays against that reference."""

import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from testbed.localization import msf as msf_module
from testbed.localization.msf import MultiSensorFusion, PrefixUpdate, observed_prefix_update, propagate_covariance
from testbed.localization.sensors import GnssFix, ImuSample, LidarFix
from tracks.pose import Pose

N = 7


def _covariance(rng: np.random.Generator) -> np.ndarray:
    a = rng.normal(size=(N, N))
    return a @ a.T + 0.1 * np.eye(N)


def _transition(rng: np.random.Generator) -> np.ndarray:
    f = np.eye(N)
    f[0, 2:5], f[1, 2:5], f[0, 6], f[1, 6], f[2, 4], f[3, 5] = rng.normal(size=3), rng.normal(size=3), *rng.normal(
        size=4)
    return f


def test_propagation_equals_filterpy_predict():
    rng = np.random.default_rng(1)
    for _ in range(50):
        p, f, q = _covariance(rng), _transition(rng), rng.uniform(0.0, 1e-3, N)
        kf = KalmanFilter(dim_x=N, dim_z=2)
        kf.x, kf.P, kf.F, kf.Q = np.zeros(N), p.copy(), f, np.diag(q)
        kf.predict()
        propagate_covariance(p, f, q, np.empty((N, N)))
        assert np.array_equal(p, kf.P)


def test_update_of_an_observed_prefix_equals_filterpy_update():
    rng = np.random.default_rng(2)
    for n in (2, 3) * 25:
        p, z = _covariance(rng), rng.normal(size=n)
        r = np.diag(rng.uniform(0.01, 1.0, n))
        h = np.hstack([np.eye(n), np.zeros((n, N - n))])
        kf = KalmanFilter(dim_x=N, dim_z=n)
        kf.x, kf.P = np.zeros(N), p.copy()
        kf.update(z, R=r, H=h)
        dx, updated = observed_prefix_update(p, z, r, p[:n, :n] + r)
        assert np.array_equal(dx, kf.x) and np.array_equal(updated, kf.P)


def test_prefix_update_equals_the_reference_update_and_gate():
    rng = np.random.default_rng(3)
    updates = {n: PrefixUpdate(n) for n in (2, 3)}
    for n in (2, 3) * 500:
        p, z = _covariance(rng) * rng.uniform(1e-4, 10.0), rng.normal(size=n) * rng.uniform(0.01, 5.0)
        a = rng.normal(size=(n, n))
        r = np.diag(rng.uniform(0.01, 1.0, n)) if n == 2 else a @ a.T + 0.01 * np.eye(n)
        s = p[:n, :n] + r
        d2 = float(z @ np.linalg.solve(s, z))
        dx, updated = observed_prefix_update(p, z, r, s)
        fast = p.copy()
        assert updates[n].distance(fast, z, r) == d2
        assert np.array_equal(updates[n].apply(fast, z, r), dx) and np.array_equal(fast, updated)


def test_prefix_update_keeps_the_reference_errors():
    update = PrefixUpdate(2)
    p = np.zeros((N, N))
    with pytest.raises(np.linalg.LinAlgError), np.errstate(invalid="ignore"):
        update.distance(p, np.array([1.0, 2.0]), np.zeros((2, 2)))  # a singular S
    assert math.isnan(update.distance(np.eye(N), np.array([math.nan, 0.0]), np.eye(2)))


def drive_filter(fusion: MultiSensorFusion, seed: int) -> list[tuple[np.ndarray, np.ndarray, dict]]:
    """3,000 IMU samples with GNSS and LiDAR fixes between them, some far enough off to be gated out and the
    LiDAR re-admitted; the state after each step."""
    rng, t, states = np.random.default_rng(seed), 0.0, []
    for k in range(3000):
        t += 0.01
        fusion.predict(ImuSample(t, float(rng.normal(0.0, 1.0)), float(rng.normal(0.05, 0.2))))
        off = 8.0 if 1200 <= k < 1800 else 0.3
        if k % 10 == 3:
            fusion.update_gnss(GnssFix(t, fusion.nominal[:2] + rng.normal(0.0, off, 2), np.eye(2) * 0.16))
        if k % 10 == 7:
            fusion.update_lidar(LidarFix(t, fusion.nominal[:2] + rng.normal(0.0, off, 2),
                                         float(fusion.nominal[2]) + rng.normal(0.0, 0.01),
                                         np.diag([0.01, 0.01, 1e-4])))
        states.append((fusion.nominal.copy(), fusion.P.copy(), dict(fusion.rejected)))
    return states


@pytest.mark.parametrize("seed", [0, 1])
def test_filter_updates_equal_the_reference_path(seed: int):
    start = Pose(3.0, 1.0, math.pi - 0.05)
    fast, reference = MultiSensorFusion(start, 15.0), MultiSensorFusion(start, 15.0)
    fast._gated = reference._gated = None  # the compiled update is held to the reference in test_msf_kernels.py
    assert fast._updates is not None or msf_module._solve1 is None
    reference._updates = None
    ours, theirs = drive_filter(fast, seed), drive_filter(reference, seed)
    assert theirs[-1][2]["gnss"] > 0 and theirs[-1][2]["lidar"] > 0  # the gate and the re-admission ran
    for (x, p, rej), (x_ref, p_ref, rej_ref) in zip(ours, theirs, strict=True):
        assert np.array_equal(x, x_ref) and np.array_equal(p, p_ref) and rej == rej_ref
