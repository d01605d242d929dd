"""Commands at the profile's period whatever the loop's rate: a cycle at every 20 ms boundary carrying the loop's
latest command while it is younger than one control period; in realtime a pacer thread keeps the period."""

import itertools
import statistics
import uuid

import can
import pytest

from hil.emulator.ecu import EcuEmulator
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.bridge import CanChassisBridge
from hil.link.codec import ChassisCodec
from hil.link.profile import load_profile
from hil.link.timing import ClockMode, CommandCycle
from testbed.chassis import ChassisCommand

PIX = load_profile("pix-hooke")


class _Sent(can.Listener):
    def __init__(self) -> None:
        self.frames: list[can.Message] = []

    def on_message_received(self, msg: can.Message) -> None:
        if not msg.is_rx:
            self.frames.append(msg)


def test_a_command_stands_for_one_control_period():
    cycle = CommandCycle(20_000)
    cycle.loop_us = 25_000
    assert cycle.at(0) is None
    command = ChassisCommand(0.1, 1.0)
    cycle.give(command, 0)
    assert cycle.at(0) is command and cycle.at(20_000) is command and cycle.at(25_000) is None
    assert cycle.is_boundary(40_000) and not cycle.is_boundary(25_000)


def _lockstep_drive_frames(loop_s: float, seconds: float) -> list[tuple[float, float]]:
    """(chassis time, throttle %) of every drive command frame of a lockstep drive whose tick k asks k/10 m/s²."""
    channel = f"cycle-{uuid.uuid4().hex}"
    ecu_bus, bridge_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    ecu = EcuEmulator(ecu_bus, KinematicBicyclePlant(), profile=PIX)
    ecu.start()
    bridge = CanChassisBridge(bridge_bus, profile=PIX)
    sent = _Sent()
    try:
        bridge.engage()
        bridge.add_listener(sent)
        for k in range(round(seconds / loop_s)):
            bridge.send(ChassisCommand(0.0, k / 10))
            bridge.advance(loop_s)
    finally:
        bridge.close()
        ecu.stop()
        bridge_bus.shutdown()
        ecu_bus.shutdown()
    codec = ChassisCodec(PIX)
    drive = [f for f in sent.frames if f.arbitration_id == PIX.frame_id(PIX.commands.drive)]
    return [(round(f.timestamp, 6), codec.decode(f).signals[PIX.commands.throttle]) for f in drive]


@pytest.mark.parametrize(("loop_s", "ticks_sent"), [
    (0.025, [0, 0, 1, 2, 3, 4, 4, 5, 6, 7]),  # 40 Hz: tick 0 at 0 and 20 ms, tick 1 at 40 ms, ...
    (0.01, [0, 2, 4, 6, 8, 10, 12, 14, 16, 18]),  # 100 Hz: every other tick
    (0.05, [0, 0, 0, 1, 1, 2, 2, 2, 3, 3]),  # 20 Hz: each command held for its control period
])
def test_lockstep_commands_go_out_every_20_ms_whatever_the_loop_rate(loop_s, ticks_sent):
    frames = _lockstep_drive_frames(loop_s, 1.0)
    times = [t for t, _ in frames]
    assert times == pytest.approx([0.02 * k for k in range(50)])
    assert [round(pct / 100 * PIX.longitudinal.full_throttle_accel * 10) for _, pct in frames[:10]] == ticks_sent


def test_realtime_commands_keep_the_profile_period_at_a_40_hz_loop():
    channel = f"cycle-rt-{uuid.uuid4().hex}"
    ecu_bus, bridge_bus, spy = (can.Bus(interface="virtual", channel=channel) for _ in range(3))
    ecu = EcuEmulator(ecu_bus, KinematicBicyclePlant(), clock=ClockMode.REALTIME, profile=PIX)
    ecu.start()
    bridge = CanChassisBridge(bridge_bus, clock=ClockMode.REALTIME, profile=PIX)
    try:
        bridge.engage()
        while spy.recv(0.0) is not None:
            pass
        for _ in range(40):  # 1 s at 40 Hz
            bridge.send(ChassisCommand(0.0, 0.5))
            bridge.advance(0.025)
        frames = []
        while (frame := spy.recv(0.0)) is not None:
            frames.append(frame)
        bridge.stop_and_release()
    finally:
        bridge.close()
        ecu.stop()
        for bus in (ecu_bus, bridge_bus, spy):
            bus.shutdown()
    drive = [f.timestamp for f in frames if f.arbitration_id == PIX.frame_id(PIX.commands.drive)]
    gaps = [b - a for a, b in itertools.pairwise(drive)]
    assert len(drive) >= 45  # 50 cycles in 1 s, not 40
    assert statistics.median(gaps) == pytest.approx(0.02, abs=0.003)
    assert max(gaps) <= 3 * 0.02
    assert not bridge.latched_faults()


def _realtime_pix() -> tuple[EcuEmulator, CanChassisBridge, list[can.BusABC]]:
    channel = f"cycle-rt-{uuid.uuid4().hex}"
    ecu_bus, bridge_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    ecu = EcuEmulator(ecu_bus, KinematicBicyclePlant(), clock=ClockMode.REALTIME, profile=PIX)
    ecu.start()
    return ecu, CanChassisBridge(bridge_bus, clock=ClockMode.REALTIME, profile=PIX), [ecu_bus, bridge_bus]


def test_a_report_backlog_before_engaging_is_no_second_sender_but_a_burst_while_engaged_is():
    """A set-up that starves the receive thread for seconds hands it a backlog before the engage: not a fault.
    The same burst while engaged is a second sender."""
    ecu, bridge, buses = _realtime_pix()
    codec = ChassisCodec(PIX)
    drive_status = PIX.reports.quantities["speed"].message
    burst = [codec.encode(drive_status, {}) for _ in range(3 * 6)]  # three slacks of 5 cycles at once
    try:
        for frame in burst:
            bridge.handle(frame)
        bridge.engage()
        assert not bridge.latched_faults()
        for frame in burst:
            bridge.handle(frame)
        assert [f.kind for f in bridge.latched_faults()][:1] == ["foreign_sender"]
    finally:
        bridge.close()
        ecu.stop()
        for bus in buses:
            bus.shutdown()


def test_realtime_commands_go_on_without_a_gap_from_the_handshake_to_the_loop():
    """The engage's hold command is sent at once and stands until the loop's first command: no cycle is missed
    between the handshake's last cycle and the loop's first."""
    ecu, bridge, buses = _realtime_pix()
    sent = _Sent()
    try:
        bridge.add_listener(sent)
        bridge.engage()
        for _ in range(8):
            bridge.send(ChassisCommand(0.0, 0.5))
            bridge.advance(0.025)
        bridge.stop_and_release()
    finally:
        bridge.close()
        ecu.stop()
        for bus in buses:
            bus.shutdown()
    drive = [f.timestamp for f in sent.frames if f.arbitration_id == PIX.frame_id(PIX.commands.drive)]
    assert max(b - a for a, b in itertools.pairwise(drive)) < 2 * 0.02
