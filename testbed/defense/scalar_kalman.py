"""A 1-D Kalman filter over the lateral deviation d (paper Alg. 2's `kf`).

Model: d_{k+1} = d_k + w, w ~ N(0, Q); measurement z = d + v, v ~ N(0, R) with R given per update.
Update: K = P / (P + R), d += K (z - d), P = (1 - K) P. Predict: P += Q.
These are filterpy's `KalmanFilter` equations for dim_x = dim_z = 1 written on floats: filterpy's
matrix version costs about 50 µs per update in CPython, over the whole fusion budget.
"""

from __future__ import annotations


class ScalarKalman:
    """Random-walk state with scalar measurements; `gain` is the Kalman gain of the last update."""

    def __init__(self, x0: float, p0: float, q: float) -> None:
        self.x = x0
        self.p = p0
        self.q = q
        self.gain: float | None = None

    def update(self, z: float, r: float) -> float:
        """Fuse measurement z with variance r; returns the Kalman gain used."""
        k = self.p / (self.p + r)
        self.x += k * (z - self.x)
        self.p *= 1.0 - k
        self.gain = k
        return k

    def predict(self) -> float:
        """Random-walk prediction: the state is unchanged, its variance grows by Q."""
        self.p += self.q
        return self.x
