import math

import numpy as np
import pytest

from testbed.localization.sensors import GnssModel, GnssSensor, Imu, LidarLocator, LidarModel
from tracks.pose import Pose, wrap_angle

TRUTH = Pose(10.0, -5.0, 0.3)


def gnss_errors(seed: int, n: int = 600, model: GnssModel | None = None) -> np.ndarray:
    g = GnssSensor(np.random.default_rng(seed), model=model)
    return np.array([g.measure(i * 0.1, TRUTH).xy - [TRUTH.x, TRUTH.y] for i in range(n)])


def test_same_seed_same_fixes_other_seed_differs():
    assert np.array_equal(gnss_errors(3, 50), gnss_errors(3, 50))
    assert not np.allclose(gnss_errors(3, 50), gnss_errors(4, 50))


def test_gnss_is_due_at_its_rate_on_a_100hz_loop():
    g = GnssSensor(np.random.default_rng(0), rate_hz=10.0)
    due = 0
    for i in range(300):
        t = i * 0.01
        if g.due(t):
            g.measure(t, TRUTH)
            due += 1
    assert due == 30


def test_gnss_error_wanders_slowly_and_reported_covariance_covers_it():
    err = gnss_errors(1, n=3000, model=GnssModel(multipath_rate=0.0))
    rms = float(np.sqrt(np.mean(err**2)))
    assert 0.03 < rms < GnssModel().reported_std
    # the bias is slow: consecutive 1-s means of the error are strongly correlated (the white noise alone
    # gives |r| < 0.06 on these seeds; the bias alone, τ = 60 s, gives r ≈ 0.98)
    x = err[:, 0] - err[:, 0].mean()
    means = x.reshape(-1, 10).mean(axis=1)
    assert float(np.corrcoef(means[:-1], means[1:])[0, 1]) > 0.5


def test_multipath_burst_adds_error_and_inflates_reported_covariance():
    model = GnssModel(multipath_rate=1e6, multipath_offset=(2.0, 2.0), multipath_duration=(5.0, 5.0))
    g = GnssSensor(np.random.default_rng(2), model=model)
    g.measure(0.0, TRUTH)
    fix = g.measure(0.1, TRUTH)
    assert g.in_multipath(0.1)
    assert np.linalg.norm(fix.xy - [TRUTH.x, TRUTH.y]) > 1.4
    assert fix.cov[0, 0] > 4 * model.reported_std**2


def lidar(q: float, seed: int = 0) -> LidarLocator:
    return LidarLocator(np.random.default_rng(seed), lambda x, y: q, model=LidarModel(occlusion_rate=0.0))


def mean_fix_offset(q: float, prior_offset: float, n: int = 200) -> tuple[float, float]:
    loc = lidar(q)
    prior = Pose(TRUTH.x, TRUTH.y + prior_offset, TRUTH.yaw)
    fixes = [loc.measure(i * 0.1, TRUTH, prior) for i in range(n)]
    return float(np.mean([f.xy[1] - TRUTH.y for f in fixes])), float(np.mean([f.cov[0, 0] for f in fixes]))


def test_lidar_converges_to_truth_where_features_are_rich():
    off, var = mean_fix_offset(1.0, 0.15)
    assert abs(off) < 0.03
    assert math.sqrt(var) < 2 * LidarModel().reported_std_rich


def test_lidar_is_dragged_by_the_prior_where_features_are_poor():
    off, var = mean_fix_offset(0.0, 0.3)
    assert 0.2 < off < 0.3
    assert math.sqrt(var) > 5 * LidarModel().reported_std_rich


def test_lidar_beyond_capture_radius_follows_prior_and_reports_it_is_lost():
    off, var = mean_fix_offset(1.0, 2.0)
    assert off == pytest.approx(2.0, abs=0.02)
    assert math.sqrt(var) > LidarModel().lost_reported_std


def test_occlusion_episodes_lower_the_effective_quality():
    loc = LidarLocator(np.random.default_rng(5), lambda x, y: 1.0, model=LidarModel(occlusion_rate=1e6))
    loc.measure(0.0, TRUTH, TRUTH)
    loc.measure(0.1, TRUTH, TRUTH)
    assert loc.quality(0.1, TRUTH.x, TRUTH.y) < 0.5
    assert lidar(1.0).quality(0.1, TRUTH.x, TRUTH.y) == 1.0


def test_imu_measures_truth_plus_bias_and_noise():
    imu = Imu(np.random.default_rng(7))
    samples = [imu.samples(i * 0.01, 0.5, 0.1)[0] for i in range(2000)]
    w = np.array([s.yaw_rate for s in samples])
    a = np.array([s.accel_long for s in samples])
    assert abs(w.mean() - 0.1) < 0.005
    assert abs(a.mean() - 0.5) < 0.2
    assert w.std() > 0.001


def test_a_slow_tick_takes_the_samples_due_since_the_last_with_the_draws_of_one_call_each():
    slow, each = Imu(np.random.default_rng(9)), Imu(np.random.default_rng(9))
    batched = [s for i in range(5) for s in slow.samples(i * 0.025, 0.3, 0.02)]  # 40 Hz ticks over 0.1 s
    assert [s.t for s in batched] == pytest.approx([0.0, 0.01, 0.025, 0.03, 0.04, 0.05, 0.06, 0.075, 0.08, 0.09, 0.1])
    one_by_one = [each.samples(s.t, 0.3, 0.02) for s in batched]
    assert all(len(one) == 1 for one in one_by_one)
    assert [one[0] for one in one_by_one] == batched  # the same instants, biases and noise, bit for bit


def test_gnss_fixes_are_the_models_arithmetic_on_2_vectors_to_the_bit():
    """The receiver keeps its error's axes as floats; the fixes are those of the model written on 2-vectors."""
    m = GnssModel(multipath_rate=0.5)
    g, rng = GnssSensor(np.random.default_rng(11), model=m), np.random.default_rng(11)
    bias, until, offset, last = rng.normal(0.0, m.bias_std, 2), -math.inf, np.zeros(2), None
    for i in range(400):
        t = 0.1 * i
        fix = g.measure(t, TRUTH)
        dt = 0.0 if last is None else t - last
        last, phi = t, math.exp(-dt / m.bias_tau)
        bias = phi * bias + math.sqrt(1.0 - phi * phi) * m.bias_std * rng.normal(size=2)
        if t >= until and rng.random() < 1.0 - math.exp(-m.multipath_rate * dt):
            until, ang = t + rng.uniform(*m.multipath_duration), rng.uniform(-math.pi, math.pi)
            offset = rng.uniform(*m.multipath_offset) * np.array([math.cos(ang), math.sin(ang)])
        err, std = bias + m.noise_std * rng.normal(size=2), m.reported_std
        if t < until:
            err = err + offset
            std = math.hypot(std, m.multipath_reported_gain * float(np.linalg.norm(offset)))
        assert np.array_equal(fix.xy, np.array([TRUTH.x, TRUTH.y]) + err)
        assert np.array_equal(fix.cov, np.eye(2) * std * std)


def test_lidar_fixes_are_the_models_arithmetic_on_2_vectors_to_the_bit():
    m = LidarModel(occlusion_rate=0.0)
    loc, rng = LidarLocator(np.random.default_rng(12), lambda x, y: 0.6, model=m), np.random.default_rng(12)
    for i in range(400):
        prior = Pose(TRUTH.x + 0.3 * math.sin(0.1 * i), TRUTH.y + 0.4 * math.cos(0.07 * i), TRUTH.yaw + 0.01)
        fix = loc.measure(0.1 * i, TRUTH, prior)
        rng.random()  # the occlusion draw
        q, offset = 0.6, np.array([prior.x - TRUTH.x, prior.y - TRUTH.y])
        captured = math.exp(-0.5 * (float(np.linalg.norm(offset)) / m.capture_radius) ** 4)
        pull = (m.pull_poor + (1.0 - m.pull_poor) * q) * captured
        std = m.noise_std_rich + (m.noise_std_poor - m.noise_std_rich) * (1.0 - q)
        yaw_std = m.yaw_std_rich + (m.yaw_std_poor - m.yaw_std_rich) * (1.0 - q)
        rep = m.reported_std_rich + (m.reported_std_poor - m.reported_std_rich) * (1.0 - q)
        rep += m.lost_reported_std * (1.0 - captured)
        xy = np.array([TRUTH.x, TRUTH.y]) + (1.0 - pull) * offset + std * rng.normal(size=2)
        yaw = TRUTH.yaw + (1.0 - pull) * wrap_angle(prior.yaw - TRUTH.yaw) + yaw_std * rng.normal()
        assert np.array_equal(fix.xy, xy) and fix.yaw == wrap_angle(yaw)
        assert np.array_equal(fix.cov, np.diag([rep * rep, rep * rep, (2.0 * yaw_std) ** 2]))
