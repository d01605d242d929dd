"""The yaw rate the loop reads from a CAN chassis: the chassis's own where its profile maps a yaw-rate report;
else from the rear wheels' rpm where it maps both, ψ̇ = (v_rr − v_rl) / track (`hil.link.wheels`); else derived
from what every profile reports through the kinematic bicycle, ψ̇ = v tan δ / L (reported speed v, road-wheel
angle δ, wheelbase L). `source` names which, for the summary."""

from __future__ import annotations

import dataclasses
from typing import Protocol

from hil.link.profile import ChassisProfile
from hil.link.wheels import WheelGeometry
from testbed.chassis import ChassisCommand, ChassisFault, ChassisPort, ChassisState, bicycle_yaw_rate
from vehicles.params import VehicleParams

REPORTED = "chassis"
WHEEL_SPEEDS = "rear wheel speeds (reported rpm, track and wheel radius)"
BICYCLE = "bicycle model (reported speed and steering angle)"
WHEEL_RPM = ("wheel_rpm_rl", "wheel_rpm_rr")


class ReportingPort(Protocol):
    """A chassis port that also gives the latest value of any report quantity (the CAN bridge)."""

    def reported(self, quantity: str) -> float | None: ...


def yaw_rate_source(profile: ChassisProfile) -> str:
    """Where the loop's yaw rate comes from on a chassis speaking `profile`."""
    quantities = profile.reports.quantities
    if "yaw_rate" in quantities:
        return REPORTED
    return WHEEL_SPEEDS if all(q in quantities for q in WHEEL_RPM) else BICYCLE


class YawRateChassis(ChassisPort):
    """`port` with its state's yaw rate from `yaw_rate_source(profile)` for a vehicle of `params`; commands and
    faults pass through. The wheel-speed source reads the rpm through `port.reported` (a `ReportingPort`)."""

    def __init__(self, port: ChassisPort, profile: ChassisProfile, params: VehicleParams) -> None:
        self.port = port
        self.source = yaw_rate_source(profile)
        self.wheelbase = params.wheelbase
        self.wheels = WheelGeometry.of(params)

    def read(self) -> ChassisState:
        state = self.port.read()
        if self.source == REPORTED:
            return state
        if self.source == WHEEL_SPEEDS:
            port: ReportingPort = self.port  # type: ignore[assignment]
            left, right = (port.reported(q) for q in WHEEL_RPM)
            yaw_rate = self.wheels.yaw_rate(left, right) if left is not None and right is not None else 0.0
            return dataclasses.replace(state, yaw_rate=yaw_rate)
        return dataclasses.replace(state, yaw_rate=bicycle_yaw_rate(state.speed, state.steer, self.wheelbase))

    def send(self, cmd: ChassisCommand) -> None:
        self.port.send(cmd)

    def advance(self, dt: float) -> None:
        self.port.advance(dt)

    def latched_faults(self) -> tuple[ChassisFault, ...]:
        return self.port.latched_faults()
