"""The bound's loop identified on the car: three short closed-loop runs give responses that start at rest and
match the linear model's peak, and the program on them stays near the model's bound; a speed the straight road
cannot hold is refused."""

from __future__ import annotations

import numpy as np
import pytest

from testbed.control.attack_bound import deviation_bound, lateral_loop
from testbed.errors import UserError
from testbed.eval.run.scenario import load_scenario
from testbed.eval.search.bound_on_car import identify
from testbed.eval.search.bound_table import bound_setting

SPEED, HORIZON_S = 8.0, 4.0


def test_the_identified_loop_matches_the_model_at_its_peak_and_bounds_alike() -> None:
    sc = load_scenario("local").replace(defense="ld3", localization="msf", detector="oracle")
    setting = bound_setting(sc)
    identified = identify(sc, SPEED, HORIZON_S)
    model = lateral_loop(setting.controller, SPEED, setting.every)
    ticks = round(HORIZON_S / model.dt) + 1
    assert identified.pulse_time_s >= 9.0 - 1e-9  # after the settling, at the detection the car is at speed
    for car, linear in zip(identified.loop.responses(ticks), model.responses(ticks), strict=True):
        assert car[0] == 0.0  # the input acts from the pulse's tick on
        assert car.min() == pytest.approx(linear.min(), rel=0.15)  # the car steers away from the input as modelled
        assert abs(int(np.argmin(car)) - int(np.argmin(linear))) <= 8  # within 0.2 s
    on_car = deviation_bound(identified.loop, setting.lateral, setting.heading, horizon_s=HORIZON_S).bound_m
    on_model = deviation_bound(model, setting.lateral, setting.heading, horizon_s=HORIZON_S).bound_m
    assert 0.2 < on_car == pytest.approx(on_model, rel=0.15)


def test_a_speed_the_straight_road_cannot_hold_is_refused() -> None:
    with pytest.raises(UserError, match=r"needs \d+ m of straight road"):
        identify(load_scenario("local").replace(defense="ld3", localization="msf"), 60.0, 10.0)
