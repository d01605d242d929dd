"""Seeded sensor models that feed the MSF: GNSS receiver, LiDAR map locator and IMU.

GNSS (10 Hz): truth + a slowly wandering bias (2-D first-order Gauss-Markov, time constant `bias_tau`)
+ white noise + multipath bursts (Poisson onsets, a few seconds each, a fixed offset of 0.5–2.5 m in a
random direction); the receiver reports a covariance that grows only partly during a burst.

LiDAR locator (10 Hz): a map matcher whose search starts at the MSF predicted pose. Where the map has
few features (the track's `feature_quality`, further reduced by random traffic-occlusion episodes) the
cost surface is flat, so the match converges only part of the way from the prior to the truth
(`pull` ∈ [pull_poor, 1]), and not at all once the prior is beyond the capture radius (pull × exp(−½(δ/r)⁴),
δ = prior error): the match is then lost and reports a large covariance. Noise and reported covariance
also grow in feature-poor stretches. The residual dependence of the match on the prior is not
in the reported covariance: a fused estimate that drifts drags the locator with it.

IMU (100 Hz): longitudinal accelerometer and yaw gyro with white noise and random-walk biases.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tracks.pose import Pose, wrap_angle


@dataclass(frozen=True)
class GnssFix:
    """A GNSS position fix in the world frame with the receiver's reported 2×2 covariance."""

    t: float
    xy: np.ndarray
    cov: np.ndarray


@dataclass(frozen=True)
class LidarFix:
    """A LiDAR-locator pose (x, y, yaw) with its reported 3×3 covariance."""

    t: float
    xy: np.ndarray
    yaw: float
    cov: np.ndarray


@dataclass(frozen=True)
class ImuSample:
    """Longitudinal specific force (m/s²) and yaw rate (rad/s) as the IMU measures them."""

    t: float
    accel_long: float
    yaw_rate: float


class _Schedule:
    """Fixed-rate sampling: `due(t)` is true once per period, on the first tick at or after each slot."""

    def __init__(self, rate_hz: float) -> None:
        if not rate_hz > 0:
            raise ValueError(f"sensor rate must be > 0 Hz, got {rate_hz}")
        self.period = 1.0 / rate_hz
        self._next: float | None = None

    def due(self, t: float) -> bool:
        return self._next is None or t >= self._next - 1e-9

    def consume(self, t: float) -> None:
        if self._next is None:
            self._next = t
        while self._next <= t + 1e-9:
            self._next += self.period

    def take(self, t: float) -> list[float]:
        """The sampling instants up to t not yet taken, the last of them t itself (the tick that reads them):
        one at a tick as often as the sensor, several at a slower tick; consumed (`consume(t)`) as they are."""
        nxt = t if self._next is None else self._next
        out: list[float] = []
        while nxt <= t + 1e-9:
            out.append(nxt)
            nxt += self.period
        self._next = nxt
        if out:
            out[-1] = t
        return out


@dataclass(frozen=True)
class GnssModel:
    """GNSS error model parameters (m, s). The bias (5 cm per axis) is that of a corrected (RTK-float or PPP)
    receiver, the grade high-level AD stacks fuse; at 8 cm the benign MSF followed the bias through LiDAR-poor
    highway stretches to 0.19 m lateral error, beyond what lane keeping on the MSF allows."""

    bias_std: float = 0.05
    bias_tau: float = 60.0
    noise_std: float = 0.08
    reported_std: float = 0.4
    multipath_rate: float = 1.0 / 90.0
    multipath_duration: tuple[float, float] = (2.0, 6.0)
    multipath_offset: tuple[float, float] = (0.5, 2.5)
    multipath_reported_gain: float = 0.8


class GnssSensor:
    """GNSS receiver: biased, noisy, occasionally multipath-corrupted position fixes (the error's two axes
    kept as floats: the same arithmetic, element for element, as on 2-vectors)."""

    def __init__(
        self, rng: np.random.Generator, rate_hz: float = 10.0, model: GnssModel | None = None
    ) -> None:
        self.rng = rng
        self.model = model or GnssModel()
        self._schedule = _Schedule(rate_hz)
        self._bias: tuple[float, float] = tuple(rng.normal(0.0, self.model.bias_std, 2).tolist())
        self._burst_until = -math.inf
        self._burst_offset = (0.0, 0.0)
        self._burst_norm = 0.0
        self._last_t: float | None = None

    def due(self, t: float) -> bool:
        return self._schedule.due(t)

    def _advance(self, t: float) -> None:
        m = self.model
        dt = 0.0 if self._last_t is None else max(0.0, t - self._last_t)
        self._last_t = t
        phi = math.exp(-dt / m.bias_tau)
        gain = math.sqrt(1.0 - phi * phi) * m.bias_std
        wx, wy = self.rng.normal(size=2).tolist()
        bx, by = self._bias
        self._bias = (phi * bx + gain * wx, phi * by + gain * wy)
        if t >= self._burst_until and self.rng.random() < 1.0 - math.exp(-m.multipath_rate * dt):
            self._burst_until = t + self.rng.uniform(*m.multipath_duration)
            ang = self.rng.uniform(-math.pi, math.pi)
            offset = self.rng.uniform(*m.multipath_offset) * np.array([math.cos(ang), math.sin(ang)])
            self._burst_offset = tuple(offset.tolist())
            self._burst_norm = float(np.linalg.norm(offset))

    def in_multipath(self, t: float) -> bool:
        return t < self._burst_until

    def measure(self, t: float, true_pose: Pose) -> GnssFix:
        m = self.model
        self._schedule.consume(t)
        self._advance(t)
        nx, ny = self.rng.normal(size=2).tolist()
        bx, by = self._bias
        ex, ey = bx + m.noise_std * nx, by + m.noise_std * ny
        std = m.reported_std
        if self.in_multipath(t):
            ox, oy = self._burst_offset
            ex, ey = ex + ox, ey + oy
            std = math.hypot(std, m.multipath_reported_gain * self._burst_norm)
        var = std * std
        return GnssFix(t, np.array([true_pose.x + ex, true_pose.y + ey]), np.array([[var, 0.0], [0.0, var]]))


@dataclass(frozen=True)
class LidarModel:
    """LiDAR-locator error model: std and reported std at feature quality 1 (rich) and 0 (poor)."""

    noise_std_rich: float = 0.02
    noise_std_poor: float = 0.06
    reported_std_rich: float = 0.04
    reported_std_poor: float = 0.3
    yaw_std_rich: float = 0.002
    yaw_std_poor: float = 0.01
    pull_poor: float = 0.15
    capture_radius: float = 0.5
    lost_reported_std: float = 1.0
    occlusion_rate: float = 1.0 / 12.0
    occlusion_duration: tuple[float, float] = (4.0, 10.0)
    occlusion_depth: tuple[float, float] = (0.4, 0.9)


class LidarLocator:
    """Map-matching locator seeded at the MSF prediction; weak where features are poor (module docstring)."""

    def __init__(
        self,
        rng: np.random.Generator,
        feature_quality: Callable[[float, float], float],
        rate_hz: float = 10.0,
        model: LidarModel | None = None,
    ) -> None:
        self.rng = rng
        self.feature_quality = feature_quality
        self.model = model or LidarModel()
        self._schedule = _Schedule(rate_hz)
        self._occluded_until = -math.inf
        self._occlusion_depth = 0.0
        self._last_t: float | None = None

    def due(self, t: float) -> bool:
        return self._schedule.due(t)

    def quality(self, t: float, x: float, y: float) -> float:
        """Effective feature quality in [0, 1]: the map's, reduced during a traffic-occlusion episode."""
        q = min(1.0, max(0.0, float(self.feature_quality(x, y))))
        if t < self._occluded_until:
            q *= 1.0 - self._occlusion_depth
        return q

    def _advance(self, t: float) -> None:
        m = self.model
        dt = 0.0 if self._last_t is None else max(0.0, t - self._last_t)
        self._last_t = t
        if t >= self._occluded_until and self.rng.random() < 1.0 - math.exp(-m.occlusion_rate * dt):
            self._occluded_until = t + self.rng.uniform(*m.occlusion_duration)
            self._occlusion_depth = self.rng.uniform(*m.occlusion_depth)

    def measure(self, t: float, true_pose: Pose, prior: Pose) -> LidarFix:
        """Match the scan against the map, starting the search from `prior` (the MSF prediction)."""
        m = self.model
        self._schedule.consume(t)
        self._advance(t)
        q = self.quality(t, true_pose.x, true_pose.y)
        poor = 1.0 - q
        ox, oy = prior.x - true_pose.x, prior.y - true_pose.y
        offset = np.array([ox, oy])
        dist = math.sqrt(float(offset.dot(offset)))  # np.linalg.norm's own arithmetic
        captured = math.exp(-0.5 * (dist / m.capture_radius) ** 4)
        pull = (m.pull_poor + (1.0 - m.pull_poor) * q) * captured
        std = m.noise_std_rich + (m.noise_std_poor - m.noise_std_rich) * poor
        yaw_std = m.yaw_std_rich + (m.yaw_std_poor - m.yaw_std_rich) * poor
        rep = m.reported_std_rich + (m.reported_std_poor - m.reported_std_rich) * poor
        rep += m.lost_reported_std * (1.0 - captured)
        nx, ny = self.rng.normal(size=2).tolist()
        held = 1.0 - pull
        xy = np.array([true_pose.x + held * ox + std * nx, true_pose.y + held * oy + std * ny])
        yaw = true_pose.yaw + (1.0 - pull) * wrap_angle(prior.yaw - true_pose.yaw) + yaw_std * self.rng.normal()
        var, yaw_var = rep * rep, (2.0 * yaw_std) ** 2
        cov = np.array([[var, 0.0, 0.0], [0.0, var, 0.0], [0.0, 0.0, yaw_var]])
        return LidarFix(t, xy, wrap_angle(yaw), cov)


@dataclass(frozen=True)
class ImuModel:
    """IMU noise: per-sample white noise and bias random-walk densities, initial bias spreads."""

    accel_std: float = 0.05
    gyro_std: float = 0.003
    accel_bias_std: float = 0.05
    gyro_bias_std: float = 0.0005
    accel_bias_walk: float = 0.002
    gyro_bias_walk: float = 0.00005


class Imu:
    """Strapdown IMU reduced to the planar channels the MSF uses."""

    def __init__(
        self, rng: np.random.Generator, rate_hz: float = 100.0, model: ImuModel | None = None
    ) -> None:
        self.rng = rng
        self.model = model or ImuModel()
        self._schedule = _Schedule(rate_hz)
        self.accel_bias = float(rng.normal(0.0, self.model.accel_bias_std))
        self.gyro_bias = float(rng.normal(0.0, self.model.gyro_bias_std))
        self._last_t: float | None = None

    def samples(self, t: float, accel: float, yaw_rate: float) -> list[ImuSample]:
        """Every sample due up to t (`_Schedule.take`: a control tick slower than the IMU reads each), all of
        the motion the tick read; the draws are those of one call per sample, taken in one call."""
        times = self._schedule.take(t)
        draws = self.rng.normal(size=4 * len(times)).tolist()
        return [self._sample(ts, accel, yaw_rate, draws[4 * k:4 * k + 4]) for k, ts in enumerate(times)]

    def _sample(self, t: float, accel: float, yaw_rate: float, draws: list[float]) -> ImuSample:
        m = self.model
        dt = 0.0 if self._last_t is None else max(0.0, t - self._last_t)
        self._last_t = t
        sq = math.sqrt(dt)
        walk_a, walk_g, noise_a, noise_g = draws  # the same draws as four scalar ones
        self.accel_bias += m.accel_bias_walk * sq * walk_a
        self.gyro_bias += m.gyro_bias_walk * sq * walk_g
        a = accel + self.accel_bias + m.accel_std * noise_a
        w = yaw_rate + self.gyro_bias + m.gyro_std * noise_g
        return ImuSample(t, a, w)
