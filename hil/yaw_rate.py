"""The yaw rate the loop reads from a CAN chassis: the chassis's own where its profile maps a yaw-rate report,
else derived from what it does report through the kinematic bicycle, ψ̇ = v tan δ / L (reported speed v,
road-wheel angle δ, wheelbase L). `source` names which, for the summary."""

from __future__ import annotations

import dataclasses
import math

from hil.profile import ChassisProfile
from testbed.chassis import ChassisCommand, ChassisFault, ChassisPort, ChassisState

REPORTED = "chassis"
BICYCLE = "bicycle model (reported speed and steering angle)"


def yaw_rate_source(profile: ChassisProfile) -> str:
    """Where the loop's yaw rate comes from on a chassis speaking `profile`."""
    return REPORTED if "yaw_rate" in profile.reports.quantities else BICYCLE


class YawRateChassis(ChassisPort):
    """`port` with its state's yaw rate from `yaw_rate_source(profile)`; commands and faults pass through."""

    def __init__(self, port: ChassisPort, profile: ChassisProfile, wheelbase: float) -> None:
        self.port = port
        self.source = yaw_rate_source(profile)
        self.wheelbase = wheelbase

    def read(self) -> ChassisState:
        state = self.port.read()
        if self.source == REPORTED:
            return state
        return dataclasses.replace(state, yaw_rate=state.speed * math.tan(state.steer) / self.wheelbase)

    def send(self, cmd: ChassisCommand) -> None:
        self.port.send(cmd)

    def advance(self, dt: float) -> None:
        self.port.advance(dt)

    def latched_faults(self) -> tuple[ChassisFault, ...]:
        return self.port.latched_faults()
