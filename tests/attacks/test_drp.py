import math

import numpy as np
import pytest

from testbed.attacks.base import AttackerView
from testbed.attacks.drp import DrpBend, DrpCreep, DrpPatch, DrpTrace
from testbed.lane_detection import LaneDetection
from tracks.pose import Pose


def ld(t: float, right: bool = True) -> LaneDetection:
    return LaneDetection(
        t,
        np.array([1.75, 0.0, 0.001, 0.0]),
        np.array([-1.75, 0.0, 0.001, 0.0]) if right else None,
        0.9,
        0.9,
        (0.0, 40.0),
    )


def view(t: float) -> AttackerView:
    return AttackerView(t, Pose(0, 0, 0), 0.0, 0.0, 10.0)


def ld_dev(d: LaneDetection) -> float:
    return -(d.left[0] + d.right[0]) / 2.0


def test_drp_trace_shifts_ld_deviation_with_ramp_and_end():
    a = DrpTrace(start=10.0, shift=0.7, ramp=1.0, duration=5.0)
    assert ld_dev(a.tamper_ld(ld(9.0), view(9.0))) == pytest.approx(0.0)
    assert a.state()["stage"] == "idle"
    assert ld_dev(a.tamper_ld(ld(10.5), view(10.5))) == pytest.approx(0.35)
    out = a.tamper_ld(ld(12.0), view(12.0))
    assert ld_dev(out) == pytest.approx(0.7)
    assert out.left[2] == pytest.approx(0.001) and a.state() == {"stage": "active", "switch_time": None, "offset": 0.7}
    assert ld_dev(a.tamper_ld(ld(15.5), view(15.5))) == pytest.approx(0.0)
    assert a.state()["stage"] == "over"


def test_drp_trace_keeps_missing_lines_missing():
    out = DrpTrace(start=0.0, shift=-0.4, ramp=0.0).tamper_ld(ld(1.0, right=False), view(1.0))
    assert out.right is None and out.left[0] == pytest.approx(1.75 + 0.4)


def test_drp_patch_describes_itself_and_validates():
    a = DrpPatch(at=120.0, width=1.0)
    assert a.describe()["at"] == 120.0 and a.state()["stage"] == "painted"
    original = ld(1.0)
    assert a.tamper_ld(original, view(1.0)) is original
    for bad in ({"at": -1.0}, {"at": 1.0, "length": 0.0}, {"at": 1.0, "darkness": 1.5}):
        with pytest.raises(ValueError, match="drp-patch"):
            DrpPatch(**bad)


def test_drp_bend_shifts_and_rotates_the_lines_with_the_ramp():
    a = DrpBend(start=10.0, shift=0.7, bend=-0.1, ramp=1.0, duration=10.0)
    assert a.tamper_ld(ld(9.0), view(9.0)).left[1] == pytest.approx(0.0)
    half = a.tamper_ld(ld(10.5), view(10.5))
    assert ld_dev(half) == pytest.approx(0.35)
    assert half.left[1] == pytest.approx(math.tan(-0.05)) and half.right[1] == pytest.approx(math.tan(-0.05))
    full = a.tamper_ld(ld(13.0), view(13.0))
    assert ld_dev(full) == pytest.approx(0.7) and full.left[1] == pytest.approx(math.tan(-0.1))
    assert full.left[2] == pytest.approx(0.001)  # curvature untouched
    assert a.tamper_ld(ld(20.5), view(20.5)).left[1] == pytest.approx(0.0)
    assert a.describe() == {"kind": "drp-bend", "start": 10.0, "shift": 0.7, "ramp": 1.0, "duration": 10.0,
                            "bend": -0.1}


@pytest.mark.parametrize("bend", [0.0, 1.0, math.inf])
def test_drp_bend_refuses_a_bend_that_does_nothing_or_is_not_an_angle(bend):
    with pytest.raises(ValueError, match="bend"):
        DrpBend(bend=bend)


def test_drp_creep_is_a_search_family_of_slow_bends_for_the_lines_attacker():
    from testbed.attacks.registry import ATTACKS
    from testbed.attacks.space import FloatDim

    component = ATTACKS.get("drp-creep")
    ramp = next(d for d in component.space if isinstance(d, FloatDim) and d.name == "ramp")
    bend = next(d for d in component.space if isinstance(d, FloatDim) and d.name == "bend")
    assert ramp.low >= 3.0 and ramp.high >= 20.0 and max(abs(bend.low), bend.high) < 0.05  # under heading_b's reach
    a = DrpCreep(start=5.0, shift=-0.3, bend=0.028, ramp=15.0, duration=30.0)
    assert ld_dev(a.tamper_ld(ld(12.5), view(12.5))) == pytest.approx(-0.15)
    assert a.describe()["kind"] == "drp-creep"
