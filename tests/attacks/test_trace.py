import math

import numpy as np
import pytest

from testbed.attacks.base import AttackerView
from testbed.attacks.trace import Trace, TraceInjection
from testbed.localization.estimate import LocalizationEstimate
from tests.localization.harness import Lane
from tracks.pose import Pose


def test_default_trace_reaches_two_metres_ten_seconds_in():
    tr = Trace.named("default")
    assert tr(10.0) == pytest.approx(2.0, abs=1e-3)
    assert tr(-1.0) == 0.0 and tr(0.0) == 0.0
    assert tr(100.0) == pytest.approx(tr.dev[-1])
    assert np.all(np.diff(tr.dev) > 0)


@pytest.mark.parametrize("lane", [Lane(), Lane(600.0), Lane(60.0)])
def test_injection_reproduces_the_trace_in_msf_deviation(lane):
    attack = TraceInjection(Trace.named("default"), start=5.0)
    worst = 0.0
    for i in range(0, 1700, 7):
        t = i * 0.01
        s = 12.0 * t
        ang = s / lane.radius if lane.radius else 0.0
        true = (
            Pose(s, 0.2, 0.0)
            if lane.radius is None
            else Pose((lane.radius - 0.2) * math.sin(ang), lane.radius - (lane.radius - 0.2) * math.cos(ang), ang)
        )
        _, phys, heading, _ = lane.frame(true.x, true.y)
        est = LocalizationEstimate(t, true, np.eye(3) * 1e-4)
        out = attack.tamper_msf(est, AttackerView(t, true, phys, heading, 12.0))
        msf_dev = lane.frame(out.pose.x, out.pose.y)[1]
        expected = attack.trace(t - 5.0)
        worst = max(worst, abs((msf_dev - phys) - expected))
        assert attack.state()["offset"] == pytest.approx(expected)
        assert attack.state()["stage"] == ("idle" if t < 5.0 else "injecting")
    assert worst < 0.01


def test_scale_flips_and_scales(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("t,dev\n0,0\n1,1\n")
    attack = TraceInjection(Trace.load(p), start=0.0, scale=-0.5)
    pose = Pose(0.0, 0.0, 0.0)
    out = attack.tamper_msf(LocalizationEstimate(0.5, pose, np.eye(3)), AttackerView(0.5, pose, 0.0, 0.0, 1.0))
    assert out.pose.y == pytest.approx(-0.25)
    assert attack.describe() == {"kind": "trace", "trace": str(p), "start": 0.0, "scale": -0.5}


@pytest.mark.parametrize(
    ("text", "word"),
    [
        ("time,dev\n0,0\n1,1\n", "header"),
        ("t,dev\n0,0\n1,x\n", ":3"),
        ("t,dev\n0,0\n0,1\n", "increase"),
        ("t,dev\n0,0\n", "two rows"),
        ("t,dev\n0,0\n1,1,2\n", ":3"),
        ("t,dev\n0,0\n1,nan\n", "finite"),
    ],
)
def test_malformed_csv_raises_a_clear_error(tmp_path, text, word):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=word):
        Trace.load(p)


def test_missing_file_and_unknown_name(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        Trace.load(tmp_path / "nope.csv")
    with pytest.raises(ValueError, match="default"):
        Trace.named("nope")
