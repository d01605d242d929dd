import dataclasses

import numpy as np
import pytest

from testbed.chassis import ChassisState
from testbed.localization.stack import GroundTruthLocalization, LocalizationConfig, LocalizationStack
from tracks.pose import Pose


def drive(seed: int, spoof=None, seconds: float = 2.0):
    stack = LocalizationStack(LocalizationConfig(), np.random.default_rng(seed), lambda x, y: 0.9, Pose(0, 0, 0), 10.0)
    ests, fixes = [], []
    for i in range(round(seconds * 100)):
        t = i * 0.01
        truth = ChassisState(t=t, speed=10.0, steer=0.0, accel=0.0, true_pose=Pose(10.0 * t, 0.0, 0.0))
        ests.append(stack.step(t, truth, spoof))
        fixes.append(stack.last_gnss)
    return ests, fixes


def test_config_from_dict_reads_sections_and_rejects_bad_input():
    cfg = LocalizationConfig.from_dict(
        {"gnss_hz": 5, "gnss": {"bias_std": 0.2}, "lidar": {"occlusion_duration": [1, 2]}}
    )
    assert cfg.gnss_hz == 5.0 and cfg.gnss.bias_std == 0.2 and cfg.lidar.occlusion_duration == (1.0, 2.0)
    assert LocalizationConfig.from_dict({}) == LocalizationConfig()
    for bad, word in [
        ({"gps": {}}, "gps"),
        ({"gnss": {"bias": 1}}, "bias"),
        ({"gnss": {"bias_std": -1}}, "bias_std"),
        ({"imu_hz": 0}, "imu_hz"),
        ({"lidar": {"occlusion_depth": [0.9, 0.1]}}, "occlusion_depth"),
        ({"msf": {"gate_prob": 1.0}}, "gate_prob"),
        ({"msf": "x"}, "msf"),
    ]:
        with pytest.raises(ValueError, match=word):
            LocalizationConfig.from_dict(bad)


def test_stack_is_seeded_and_tracks_the_truth():
    a, _ = drive(1)
    b, _ = drive(1)
    c, _ = drive(2)
    assert [e.pose for e in a] == [e.pose for e in b]
    assert [e.pose for e in a] != [e.pose for e in c]
    assert abs(a[-1].pose.y) < 0.1 and abs(a[-1].pose.x - 19.9) < 0.1


def test_last_gnss_is_the_consumed_possibly_spoofed_fix():
    def spoof(fix):
        return dataclasses.replace(fix, xy=fix.xy + np.array([0.0, 0.5]))

    _, fixes = drive(1, spoof, seconds=1.0)
    consumed = [f for f in fixes if f is not None]
    assert len(consumed) == 10
    assert fixes[1] is None
    assert all(f.xy[1] > 0.1 for f in consumed)


def test_ground_truth_localization_returns_the_true_pose():
    loc = GroundTruthLocalization()
    est = loc.step(1.0, ChassisState(t=1.0, speed=3.0, steer=0.0, accel=0.0, true_pose=Pose(1, 2, 0.5)))
    assert est.pose == Pose(1, 2, 0.5) and est.cov[0, 0] < 1e-3 and loc.last_gnss is None
    with pytest.raises(ValueError):
        loc.step(0.0, ChassisState(t=0.0, speed=0.0, steer=0.0, accel=0.0))


@pytest.mark.parametrize("control_hz", [100.0, 40.0, 20.0])
def test_the_imu_feeds_the_msf_at_its_own_rate_whatever_the_control_rate(control_hz):
    stack = LocalizationStack(LocalizationConfig(), np.random.default_rng(3), lambda x, y: 0.9, Pose(0, 0, 0), 10.0)
    predicted: list[float] = []
    predict = stack.msf.predict
    stack.msf.predict = lambda sample: (predicted.append(sample.t), predict(sample))
    ticks = [round(i / control_hz, 9) for i in range(round(control_hz) + 1)]  # one second, both ends
    for t in ticks:
        stack.step(t, ChassisState(t=t, speed=10.0, steer=0.0, accel=0.0, true_pose=Pose(10.0 * t, 0.0, 0.0)))
    assert len(predicted) == 101  # 100 Hz
    assert set(ticks) <= set(predicted)  # a tick's last sample is taken at the tick itself
    assert all(0.0 < d < 0.015 + 1e-9 for d in np.diff(predicted))

