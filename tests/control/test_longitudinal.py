"""PI speed controller: tracking under drag, anti-windup, limits, standstill brake hold."""

from __future__ import annotations

from testbed.control.longitudinal import SpeedController
from testbed.control.plan import Plan

DT = 0.01


def cruise(speed: float, accel: float = 0.0) -> Plan:
    return Plan(0.0, 0.0, 0.0, speed, accel, 0.0)


def run(ctl: SpeedController, plan: Plan, v: float, seconds: float, drag: float = 0.0) -> list[float]:
    """First-order accel actuator (τ = 0.1 s) and a constant resistive deceleration `drag`."""
    a, speeds = 0.0, []
    for _ in range(round(seconds / DT)):
        cmd = ctl.update(plan, v, DT)
        a += (cmd - a) * DT / 0.1
        v = max(v + (a - drag) * DT, 0.0)
        speeds.append(v)
    return speeds


def test_tracks_speed_against_unmodelled_drag() -> None:
    speeds = run(SpeedController(), cruise(27.0), 25.0, 30.0, drag=0.6)
    assert all(abs(v - 27.0) < 0.3 for v in speeds[-1000:])
    assert abs(speeds[-1] - 27.0) < 0.05  # the integral removes the drag offset


def test_anti_windup_limits_overshoot_after_saturation() -> None:
    ctl = SpeedController(max_accel=1.0)
    speeds = run(ctl, cruise(20.0), 0.0, 40.0)  # saturated at max_accel for ~20 s
    assert max(speeds) < 20.3
    assert abs(speeds[-1] - 20.0) < 0.05


def test_commands_stay_within_limits() -> None:
    ctl = SpeedController(max_accel=2.0, max_decel=6.0)
    assert ctl.update(cruise(40.0, 5.0), 0.0, DT) == 2.0
    assert ctl.update(cruise(0.5, -9.0), 30.0, DT) == -6.0


def test_feed_forward_passes_target_accel_through_when_on_profile() -> None:
    ctl = SpeedController()
    assert ctl.update(cruise(20.0, -4.0), 20.0, DT) == -4.0


def test_brake_hold_at_standstill() -> None:
    ctl = SpeedController(hold_brake=2.0)
    run(ctl, cruise(5.0), 0.0, 3.0)
    assert ctl.update(cruise(0.0), 0.05, DT) == -2.0
    assert ctl.update(cruise(0.0), 0.0, DT) == -2.0
    # a target of zero while still rolling brakes proportionally, not with the hold
    assert -2.0 < ctl.update(cruise(0.0), 0.5, DT) < 0.0
