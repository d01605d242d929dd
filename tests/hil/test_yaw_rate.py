"""The loop's yaw rate on a CAN chassis: the chassis's report where the profile maps one, else v tan δ / L."""

import dataclasses
import math

import pytest

from hil.kinematic_plant import KinematicBicyclePlant
from hil.profile import load_profile
from hil.yaw_rate import BICYCLE, REPORTED, YawRateChassis
from testbed.chassis import ChassisCommand


class NoYawRate(KinematicBicyclePlant):
    """A plant that reports 0 for its yaw rate, as the bridge does for a profile that maps none."""

    def read(self):
        return dataclasses.replace(super().read(), yaw_rate=0.0)


def test_a_profile_without_a_yaw_rate_report_gets_the_bicycle_models():
    port = YawRateChassis(NoYawRate(wheelbase=2.5, speed=4.0), load_profile("ld3-dev"), 2.5)
    port.send(ChassisCommand(steer=0.2, accel=0.0))
    port.advance(0.1)
    state = port.read()
    assert port.source == BICYCLE
    assert state.yaw_rate == pytest.approx(state.speed * math.tan(0.2) / 2.5) and state.yaw_rate > 0.3


def test_a_profile_with_a_yaw_rate_report_passes_it_through():
    profile = load_profile("ld3-dev")
    quantities = {**profile.reports.quantities, "yaw_rate": profile.reports.quantities["speed"]}
    profile = dataclasses.replace(profile, reports=dataclasses.replace(profile.reports, quantities=quantities))
    port = YawRateChassis(NoYawRate(speed=4.0), profile, 2.5)
    port.send(ChassisCommand(steer=0.2, accel=0.0))
    assert port.source == REPORTED and port.read().yaw_rate == 0.0
