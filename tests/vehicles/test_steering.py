import math

import pytest

from vehicles.steering import SteeringActuator, ackermann_angles, bicycle_angle


@pytest.mark.parametrize("delta", [-0.5, -0.1, -1e-4, 0.0, 1e-4, 0.2, 0.6])
def test_ackermann_round_trip(delta):
    left, right = ackermann_angles(delta, 2.85, 1.6)
    assert bicycle_angle(left, right) == pytest.approx(delta, abs=1e-12)


def test_inner_wheel_turns_more_and_wheels_share_one_turn_centre():
    left, right = ackermann_angles(0.3, 2.85, 1.6)
    assert left > 0.3 > right > 0.0
    radius = 2.85 / math.tan(0.3)  # turn centre on the rear axle line, to the left
    assert 2.85 / math.tan(left) == pytest.approx(radius - 0.8)
    assert 2.85 / math.tan(right) == pytest.approx(radius + 0.8)


def test_actuator_respects_rate_and_angle_limits():
    act = SteeringActuator(max_angle=0.5, max_rate=0.6)
    dt = 0.01
    angles = [act.step(2.0, dt) for _ in range(120)]
    steps = [b - a for a, b in zip([0.0, *angles], angles, strict=False)]
    assert max(steps) == pytest.approx(0.6 * dt)
    assert angles[-1] == 0.5
    assert angles[int(0.5 / 0.6 / dt) - 2] < 0.5
    assert act.step(0.5, dt) == 0.5 and act.rate == 0.0
