"""Fault drills: a scenario over the CAN link with an emulated chassis, and one fault injected at chassis time
`at`; the run must brake to standstill in lane and end as chassis_fault.

Drills (what is injected -> the fault the bridge must latch):
  report_timeout   the ECU stops publishing reports            -> report_timeout
  ecu_lost         the ECU stops answering altogether          -> ecu_lost
  chassis_estop    the chassis's own e-stop is pressed         -> chassis_estop
  chassis_fault    the chassis reports a fatal steering fault  -> chassis_fault
  foreign_command  another node sends one valid command frame  -> foreign_sender
  foreign_report   another node sends one extra speed report   -> foreign_sender
  bus_error        an error frame appears on the bus           -> bus_error
  bus_off          the bridge's controller goes bus-off         -> bus_error
  send_error       the bus refuses the bridge's frames         -> send_error
  nan_command      the loop's acceleration becomes NaN         -> bad_command
`ld3 hil SCENARIO --drill KIND[@T]` runs one from the command line (in-process ECU only).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can

from hil.emulator.scenario_run import HilLink, LinkConfig, run_hil_scenario
from hil.link.bridge import CanChassisBridge
from hil.link.codec import ChassisCodec
from hil.link.report_map import FaultLevel
from testbed.chassis import ChassisCommand
from testbed.errors import UserError
from testbed.eval.run.outputs import chassis_faults
from testbed.eval.run.scenario import Scenario

EXPECTED = {
    "report_timeout": "report_timeout", "ecu_lost": "ecu_lost", "chassis_estop": "chassis_estop",
    "chassis_fault": "chassis_fault", "foreign_command": "foreign_sender", "foreign_report": "foreign_sender",
    "bus_error": "bus_error", "bus_off": "bus_error", "send_error": "send_error", "nan_command": "bad_command",
}
DRILL_REPLY_TIMEOUT_S = 0.5


class DropFrames:
    """Stands in for a bus's `send`: frames with an ID in `drop_ids` are swallowed, the rest pass."""

    def __init__(self, bus: can.BusABC, drop_ids: frozenset[int]) -> None:
        self.bus = bus
        self.drop_ids = drop_ids

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.arbitration_id not in self.drop_ids:
            self.bus.send(msg, timeout)


class FailingBus:
    """Stands in for the bridge's bus once a drill fires: refuses every frame, or reports bus-off."""

    def __init__(self, bus: can.BusABC, refuse: bool) -> None:
        self.bus = bus
        self.refuse = refuse

    @property
    def state(self) -> can.BusState:
        return can.BusState.ACTIVE if self.refuse else can.BusState.ERROR

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.refuse:
            raise can.CanOperationError("transmit buffer full (drill)")
        self.bus.send(msg, timeout)


class _Trigger(can.Listener):
    """Fires `action` once, on the first frame the bridge sends at or after chassis time `at`."""

    def __init__(self, bridge: CanChassisBridge, at: float, action: Callable[[], None]) -> None:
        self.bridge, self.at, self.action = bridge, at, action
        self.fired_at: float | None = None

    def on_message_received(self, msg: can.Message) -> None:
        if self.fired_at is None and not msg.is_rx and self.bridge.time() >= self.at:
            self.fired_at = self.bridge.time()
            self.action()


def _intruder_send(link: HilLink, frame: can.Message) -> None:
    intruder = can.Bus(interface="virtual", channel=link.channel)
    try:
        intruder.send(frame)
    finally:
        intruder.shutdown()


def _action(kind: str, link: HilLink) -> Callable[[], None]:
    ecu, bridge, profile = link.ecu, link.bridge, link.profile
    if ecu is None:
        raise UserError("fault drills need the in-process ECU emulator (--interface virtual)")
    codec = ChassisCodec(profile, link.key)
    if kind == "report_timeout":
        return lambda: setattr(ecu, "bus", DropFrames(ecu.bus, profile.report_ids))
    if kind == "ecu_lost":
        return ecu.stop
    if kind == "chassis_estop":
        return ecu.press_estop
    if kind == "chassis_fault":
        return lambda: ecu.inject_fault("steer_fault", int(FaultLevel.FATAL))
    if kind == "foreign_command":
        drive = profile.commands.drive
        return lambda: _intruder_send(link, codec.encode(drive, {profile.commands.drive_enable: 1}))
    if kind == "foreign_report":
        speed = profile.reports.quantities["speed"]
        return lambda: _intruder_send(link, codec.encode(speed.message, {speed.signal: 9.0}))
    if kind == "bus_error":
        return lambda: _intruder_send(link, can.Message(is_error_frame=True))
    if kind in ("bus_off", "send_error"):
        return lambda: setattr(bridge, "bus", FailingBus(bridge.bus, refuse=kind == "send_error"))
    if kind == "nan_command":
        send = bridge.send
        return lambda: setattr(bridge, "send", lambda cmd: send(ChassisCommand(cmd.steer, math.nan)))
    raise UserError(f"unknown fault drill {kind!r}; choose one of {', '.join(EXPECTED)}")


def parse_drill(text: str) -> tuple[str, float]:
    """"KIND" or "KIND@T" (T in s, default 1.5) -> (kind, at)."""
    kind, _, at = text.partition("@")
    if kind not in EXPECTED:
        raise UserError(f"unknown fault drill {kind!r}; choose one of {', '.join(EXPECTED)}")
    try:
        when = float(at) if at else 1.5
    except ValueError:
        raise UserError(f"--drill takes KIND@SECONDS, got {text!r}") from None
    if not (math.isfinite(when) and when >= 0):
        raise UserError(f"--drill {text}: the time must be a finite number of seconds >= 0, got {at}")
    return kind, when


def drill_installer(kind: str, at: float) -> Callable[[HilLink], None]:
    """The `prepare` hook of run_hil_scenario that arms drill `kind` at chassis time `at`."""

    def install(link: HilLink) -> None:
        link.bridge.add_listener(_Trigger(link.bridge, at, _action(kind, link)))

    return install


@dataclass(frozen=True)
class DrillResult:
    """One row of the fault table."""

    drill: str
    expected: str
    detected: str | None
    injected_s: float
    detected_s: float | None
    standstill_s: float | None
    outputs: tuple[str, ...]
    summary: dict[str, Any]

    @property
    def detection_latency_s(self) -> float | None:
        return None if self.detected_s is None else self.detected_s - self.injected_s


def run_drill(sc: Scenario, kind: str, out_dir: Path, at: float = 1.5, profile: str = "ld3-dev") -> DrillResult:
    """Run `sc` with drill `kind` fired at `at` s; the outputs go to `out_dir`."""
    result = run_hil_scenario(sc, out_dir, LinkConfig("virtual", profile=profile),
                              prepare=drill_installer(kind, at), reply_timeout=DRILL_REPLY_TIMEOUT_S)
    faults = chassis_faults(result.summary)
    first = faults[0] if faults else None
    outputs = tuple(sorted(p.name for p in out_dir.iterdir() if p.is_file()))
    return DrillResult(kind, EXPECTED[kind], first["kind"] if first else None, at,
                       first["time"] if first else None, result.summary["stop_time_s"], outputs, result.summary)
