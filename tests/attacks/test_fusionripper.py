import math

import numpy as np
import pytest

from testbed.attacks.base import AttackerView
from testbed.attacks.fusionripper import FusionRipper
from testbed.localization.sensors import GnssFix
from tracks.pose import Pose


def view(t: float, phys: float, heading: float = 0.0) -> AttackerView:
    return AttackerView(t, Pose(0.0, 0.0, heading), phys, heading, 10.0)


def fix(t: float) -> GnssFix:
    return GnssFix(t, np.array([1.0, 2.0]), np.eye(2) * 0.09)


def test_idle_before_start_then_constant_profiling_offset():
    a = FusionRipper(d=0.5, f=1.3, start=10.0, obs_std=0.0)
    out = a.spoof_gnss(fix(5.0), view(5.0, 0.0))
    assert np.array_equal(out.xy, [1.0, 2.0])
    assert a.state() == {"stage": "idle", "switch_time": None, "offset": 0.0}
    out = a.spoof_gnss(fix(10.0), view(10.0, 0.0))
    assert np.allclose(out.xy, [1.0, 2.5])  # heading 0: left is +y
    assert a.state()["stage"] == "profiling" and a.state()["offset"] == 0.5


def test_offset_is_lateral_to_the_lane_heading():
    a = FusionRipper(d=1.0, direction="right", start=0.0, obs_std=0.0)
    out = a.spoof_gnss(fix(0.0), view(0.0, 0.0, heading=math.pi / 2))
    assert np.allclose(out.xy, [2.0, 2.0])  # heading north: right is +x


def test_switches_only_when_pushed_the_attacked_way_then_grows_by_f_each_second():
    a = FusionRipper(d=0.5, f=1.2, direction="left", start=0.0, trigger=0.3, obs_std=0.0)
    a.spoof_gnss(fix(1.0), view(1.0, +0.5))  # deviation to the left: not the spoofing's effect
    a.spoof_gnss(fix(1.1), view(1.1, math.nan))  # off the map: no trigger
    a.spoof_gnss(fix(1.2), view(1.2, -0.29))
    assert a.state()["stage"] == "profiling"
    a.spoof_gnss(fix(2.0), view(2.0, -0.31))
    assert a.state()["stage"] == "aggressive" and a.switch_time == 2.0
    offsets = {}
    for k, tt in enumerate([2.5, 3.0, 3.9, 4.0, 5.5]):
        a.spoof_gnss(fix(tt), view(tt, 0.0 if k else -1.0))
        offsets[tt] = a.state()["offset"]
    assert offsets[2.5] == pytest.approx(0.5)
    assert offsets[3.0] == pytest.approx(0.6)
    assert offsets[3.9] == pytest.approx(0.6)
    assert offsets[4.0] == pytest.approx(0.72)
    assert offsets[5.5] == pytest.approx(0.5 * 1.2**3)
    assert a.state()["stage"] == "aggressive"  # no way back


def test_observation_noise_is_seeded():
    def switch(seed: int) -> float | None:
        a = FusionRipper(d=0.5, start=0.0, trigger=0.3, obs_std=0.05, rng=np.random.default_rng(seed))
        for i in range(200):
            a.spoof_gnss(fix(i * 0.1), view(i * 0.1, -0.27))
        return a.switch_time

    assert switch(1) == switch(1) is not None
    assert len({switch(s) for s in range(6)}) > 1


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [
        ({"d": 0}, "d"),
        ({"f": 0.9}, "f"),
        ({"direction": "up"}, "direction"),
        ({"trigger": -1}, "trigger"),
        ({"start": -1}, "start"),
        ({"obs_std": math.nan}, "obs_std"),
    ],
)
def test_bad_parameters_raise(kwargs, word):
    with pytest.raises(ValueError, match=word):
        FusionRipper(**kwargs)


def test_describe_is_the_spec():
    a = FusionRipper(d=0.7, f=1.5, direction="right", start=12.0, trigger=0.4)
    assert a.describe() == {
        "kind": "fusionripper",
        "d": 0.7,
        "f": 1.5,
        "direction": "right",
        "start": 12.0,
        "trigger": 0.4,
        "obs_std": 0.02,
    }
