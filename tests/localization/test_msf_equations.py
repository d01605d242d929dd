"""The MSF's covariance propagation and measurement update against filterpy's KalmanFilter, bit for bit."""

import numpy as np
from filterpy.kalman import KalmanFilter

from testbed.localization.msf import observed_prefix_update, propagate_covariance

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
