"""The lateral loop of every shipped vehicle at every control rate a run can choose (multiples of the default
camera rate, the chassis profiles' command rates and their multiples, 20–100 Hz) with the shipped steering-rate
weight: stable, and gain and phase margins above the floors of `testbed.eval.analysis.lateral_loop` on the design model
with the command a tick late and on the car as measured, at speeds up to the vehicle's top speed. The
combinations below the floors today are strict xfails: each is a finding, and fixing one fails its xfail."""

from __future__ import annotations

import numpy as np
import pytest

from hil.link.profile import PROFILES_DIR, load_profile
from testbed.control.config import ControlConfig
from testbed.control.lateral_model import LateralModel
from testbed.eval.analysis.lateral_loop import FLOORED, LateralLoop
from testbed.rates import CAMERA_HZ, CONTROL_HZ, PHYSICS_HZ
from vehicles.params import VEHICLES

MAX_RATE_HZ = 100.0


def choosable_rates() -> list[float]:
    camera = CAMERA_HZ
    bases = [camera] + [1.0 / load_profile(p.name).timing.cycle_s for p in sorted(PROFILES_DIR.iterdir())
                        if p.is_dir()]
    rates = {round(k * b, 6) for b in bases for k in range(1, int(MAX_RATE_HZ // b) + 1)}
    return sorted(rates | {CONTROL_HZ})


KNOWN_BELOW_FLOOR = {
    ("sedan", 20.0, "car"): "unstable: the 20 Hz loop rings on the stiff car",
    ("sedan", 20.0, "design-delayed"): "phase margin about 15° with the command a tick late",
    ("sedan", 40.0, "design-delayed"): "phase margin about 28° with the command a tick late",
    ("sedan", 80.0, "car"): "gain margin about 2 dB on the stiff car",
    ("sedan", 100.0, "car"): "gain margin about 4 dB on the stiff car",
}


def _cases() -> list:
    cases = []
    for vehicle in sorted(VEHICLES):
        for hz in choosable_rates():
            for model in FLOORED:
                key = (vehicle, hz, model.name)
                marks = [pytest.mark.xfail(strict=True, reason=KNOWN_BELOW_FLOOR[key])] if key in KNOWN_BELOW_FLOOR \
                    else []
                cases.append(pytest.param(vehicle, hz, model, marks=marks, id=f"{vehicle}-{hz:g}hz-{model.name}"))
    return cases


def test_the_choosable_rates_include_the_default_and_the_profiles_command_rate() -> None:
    rates = choosable_rates()
    assert {20.0, 40.0, 50.0, 100.0} <= set(rates) and max(rates) <= MAX_RATE_HZ


@pytest.mark.parametrize(("vehicle", "hz", "model"), _cases())
def test_loop_is_stable_with_margins_above_the_floors(vehicle, hz, model) -> None:
    params = VEHICLES[vehicle]
    loop = LateralLoop(LateralModel.from_vehicle(params), params.max_steer, hz, ControlConfig().steer_rate_weight,
                       model, PHYSICS_HZ)
    top = min(params.max_speed, 40.0)
    speeds = sorted({*np.arange(1.0, top + 1e-9, 3.0), top})
    below = [p for p in (loop.point(float(v)) for v in speeds) if not p.meets()]
    assert not below, below


def test_the_check_fails_on_a_ringing_loop() -> None:
    params = VEHICLES["sedan"]
    plain = LateralLoop(LateralModel.from_vehicle(params), params.max_steer, 40.0, 0.0, FLOORED[1], PHYSICS_HZ)
    point = plain.point(27.0)
    assert not point.stable and not point.meets()
