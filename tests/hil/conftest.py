"""Fixtures of the CAN link tests: a virtual-bus link (ECU + bridge) on a unique channel; a sync host."""

from __future__ import annotations

import uuid
from collections.abc import Iterator

import can
import pytest

from hil.emulator.ecu import EcuEmulator, EcuLimits
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.actuator_map import ActuatorRequest
from hil.link.bridge import CanChassisBridge
from hil.link.codec import ChassisCodec
from hil.link.timing import CommandCycle
from testbed.chassis import ChassisCommand, ChassisPort, ChassisState


class SampleAndHoldPort(ChassisPort):
    """The direct-run reference: the 50 Hz rule of hil.link.timing applied to a plant with no bus in between (ticks
    that divide the cycle)."""

    def __init__(self, plant: ChassisPort) -> None:
        self.plant = plant
        self._cycle = CommandCycle()
        self._t_us = 0

    def read(self) -> ChassisState:
        return self.plant.read()

    def send(self, cmd: ChassisCommand) -> None:
        self._cycle.give(cmd, self._t_us)

    def advance(self, dt: float) -> None:
        self._cycle.loop_us = round(dt * 1e6)
        command = self._cycle.at(self._t_us) if self._cycle.is_boundary(self._t_us) else None
        if command is not None:
            self.plant.send(command)
        self.plant.advance(dt)
        self._t_us += round(dt * 1e6)


class SyncHost:
    """Drives an EcuEmulator synchronously (no bus threads): frames in through `handle`, steps by `step`."""

    def __init__(self, ecu: EcuEmulator) -> None:
        self.ecu = ecu
        self.codec = ChassisCodec()
        self.step_count = 0

    def cycle_frames(self, cmd: ChassisCommand, enable: bool = True) -> list[can.Message]:
        request = ActuatorRequest.from_command(cmd, enable=enable, steer_rate=10.0)
        return [self.codec.encode(name, signals) for name, signals in request.to_signals().items()]

    def cycle(self, cmd: ChassisCommand, enable: bool = True) -> None:
        for frame in self.cycle_frames(cmd, enable):
            self.ecu.handle(frame)

    def step(self, dt: float) -> None:
        self.step_count += 1
        request = self.codec.profile.simulation.step_request
        self.ecu.handle(self.codec.encode(request, {"StepCount": self.step_count, "StepDt": dt}))


@pytest.fixture
def sync_ecu() -> Iterator[tuple[SyncHost, EcuEmulator, KinematicBicyclePlant]]:
    bus = can.Bus(interface="virtual", channel=f"hil-sync-{uuid.uuid4().hex}")
    plant = KinematicBicyclePlant()
    ecu = EcuEmulator(bus, plant, EcuLimits())
    yield SyncHost(ecu), ecu, plant
    bus.shutdown()


@pytest.fixture
def channel() -> str:
    return f"hil-test-{uuid.uuid4().hex}"


@pytest.fixture
def link(channel: str) -> Iterator[tuple[CanChassisBridge, EcuEmulator, KinematicBicyclePlant]]:
    """An in-process lockstep ECU with a kinematic plant and a bridge on one virtual channel (not engaged)."""
    ecu_bus = can.Bus(interface="virtual", channel=channel)
    bridge_bus = can.Bus(interface="virtual", channel=channel)
    plant = KinematicBicyclePlant()
    ecu = EcuEmulator(ecu_bus, plant)
    ecu.start()
    bridge = CanChassisBridge(bridge_bus)
    yield bridge, ecu, plant
    bridge.close()
    ecu.stop()
    bridge_bus.shutdown()
    ecu_bus.shutdown()
