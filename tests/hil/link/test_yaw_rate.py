"""The loop's yaw rate on a CAN chassis: the chassis's report where the profile maps one, else the rear wheels'
rpm where it maps both, else v tan δ / L."""

import dataclasses
import math
import shutil
import uuid
from pathlib import Path

import can
import pytest

from hil.emulator.ecu import EcuEmulator
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.bridge import CanChassisBridge
from hil.link.profile import PROFILES_DIR, load_profile
from hil.link.wheels import WheelGeometry
from hil.link.yaw_rate import BICYCLE, REPORTED, WHEEL_SPEEDS, YawRateChassis
from testbed.chassis import ChassisCommand
from vehicles.params import get_vehicle

DEV = get_vehicle("dev-chassis")


class NoYawRate(KinematicBicyclePlant):
    """A plant that reports 0 for its yaw rate, as the bridge does for a profile that maps none."""

    def read(self):
        return dataclasses.replace(super().read(), yaw_rate=0.0)


def test_a_profile_without_a_yaw_rate_report_gets_the_bicycle_models():
    port = YawRateChassis(NoYawRate(wheelbase=2.4, speed=4.0), load_profile("ld3-dev"), DEV)
    port.send(ChassisCommand(steer=0.2, accel=0.0))
    port.advance(0.1)
    state = port.read()
    assert port.source == BICYCLE
    assert state.yaw_rate == pytest.approx(state.speed * math.tan(0.2) / 2.4) and state.yaw_rate > 0.3


def test_a_profile_with_a_yaw_rate_report_passes_it_through():
    profile = load_profile("ld3-dev")
    quantities = {**profile.reports.quantities, "yaw_rate": profile.reports.quantities["speed"]}
    profile = dataclasses.replace(profile, reports=dataclasses.replace(profile.reports, quantities=quantities))
    port = YawRateChassis(NoYawRate(speed=4.0), profile, DEV)
    port.send(ChassisCommand(steer=0.2, accel=0.0))
    assert port.source == REPORTED and port.read().yaw_rate == 0.0


def wheel_rpm_profile(folder: Path) -> str:
    """A copy of pix-hooke in `folder` that maps the rear wheels' rpm of PIX's 0x539 report; its path."""
    profile = folder / "pix-wheels"
    shutil.copytree(PROFILES_DIR / "pix-hooke", profile)
    text = (profile / "profile.toml").read_text().replace(
        'steer = "SteerStaFb.ChassisSteerAngleFb"\n',
        'steer = "SteerStaFb.ChassisSteerAngleFb"\nwheel_rpm_rl = "ChassisWheelRpmFb.ChassisWheelRpmLr"\n'
        'wheel_rpm_rr = "ChassisWheelRpmFb.ChassisWheelRpmRr"\n')
    (profile / "profile.toml").write_text(text)
    return str(profile)


def test_a_profile_with_rear_wheel_rpm_gets_the_yaw_rate_from_the_wheel_speeds(tmp_path):
    """PIX's integer rpm: one rpm of one wheel is 2π·0.3/60 / 1.36 = 0.023 rad/s of yaw rate on dev-chassis."""
    profile = load_profile(wheel_rpm_profile(tmp_path))
    channel = f"wheels-{uuid.uuid4().hex}"
    ecu_bus, bridge_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    plant = KinematicBicyclePlant(wheelbase=DEV.wheelbase)
    ecu = EcuEmulator(ecu_bus, plant, profile=profile, wheels=WheelGeometry.of(DEV))
    ecu.start()
    bridge = CanChassisBridge(bridge_bus, profile=profile)
    port = YawRateChassis(bridge, profile, DEV)
    try:
        bridge.engage()
        for _ in range(100):  # 2 s at 2 m/s², steering 0.15 rad left
            port.send(ChassisCommand(steer=0.15, accel=2.0))
            port.advance(0.02)
        state, truth = port.read(), plant.read()
    finally:
        bridge.close()
        ecu.stop()
        bridge_bus.shutdown()
        ecu_bus.shutdown()
    assert port.source == WHEEL_SPEEDS
    assert truth.yaw_rate > 0.2 and state.yaw_rate == pytest.approx(truth.yaw_rate, abs=0.023)
    assert state.yaw_rate != pytest.approx(truth.yaw_rate, abs=1e-6)  # quantised to whole rpm on the wire
