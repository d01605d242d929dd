"""Bridge over the virtual bus: handshake, agreement with the direct run, faults, foreign node, recording."""

import math
import time

import can
import pytest

from hil.emulator.ecu import EcuEmulator, EcuLimits
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.emulator.log_replay import replay_log
from hil.link.actuator_map import ActuatorRequest
from hil.link.bridge import CanChassisBridge
from hil.link.codec import ChassisCodec
from hil.link.recorder import FrameRecorder
from hil.link.timing import ClockMode
from testbed.chassis import ChassisCommand
from tests.hil.link.driving import START, direct_run, run, start_odometry


def test_engage_reports_standby_then_self_driving(link):
    bridge, _, _ = link
    assert bridge.read().mode == "no-report"
    bridge.engage()
    state = bridge.read()
    assert state.mode == "self-driving" and state.faults == () and state.t == 0.0
    bridge.release()
    assert bridge.read().mode == "standby"


def test_virtual_bus_run_stays_within_5_cm_of_the_direct_run(channel):
    ecu_bus, bridge_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    # steering limits wide enough that the VCU never clips this controller (the direct run has none)
    ecu = EcuEmulator(ecu_bus, KinematicBicyclePlant(pose=START), EcuLimits(max_steer_rate=5.0))
    ecu.start()
    bridge = CanChassisBridge(bridge_bus, steer_rate=5.0, odometry=start_odometry())
    try:
        bridge.engage()
        over_can = run(bridge, 1500)
    finally:
        bridge.close()
        ecu.stop()
        bridge_bus.shutdown()
        ecu_bus.shutdown()
    direct = direct_run(1500)
    gaps = [math.hypot(a.x - b.x, a.y - b.y) for a, b in zip(over_can, direct, strict=True)]
    assert direct[-1].x > 40.0
    assert max(gaps) < 0.05
    assert not any(f.steer_limited for f in [ecu.report()])
    assert sum(bridge.rejected.values()) == 0


class LossyBus(can.BusABC):
    """A virtual bus that drops every command frame it is asked to send once `drop_commands` is set."""

    def __init__(self, channel: str) -> None:
        self.inner = can.Bus(interface="virtual", channel=channel)
        self.drop_commands = False
        super().__init__(channel=channel)

    def send(self, msg, timeout=None):
        if not (self.drop_commands and msg.arbitration_id in (0x130, 0x131, 0x132)):
            self.inner.send(msg, timeout)

    def _recv_internal(self, timeout):
        return self.inner.recv(timeout), False

    def shutdown(self):
        super().shutdown()
        self.inner.shutdown()


def test_lost_commands_surface_timeout_fault_and_standstill_in_state(channel):
    ecu_bus, bridge_bus = can.Bus(interface="virtual", channel=channel), LossyBus(channel)
    plant = KinematicBicyclePlant()
    ecu = EcuEmulator(ecu_bus, plant)
    ecu.start()
    bridge = CanChassisBridge(bridge_bus)
    try:
        bridge.engage()
        for _ in range(200):
            bridge.send(ChassisCommand(0.0, 2.0))
            bridge.advance(0.01)
        assert bridge.read().speed > 3.0
        bridge_bus.drop_commands = True
        for _ in range(200):
            bridge.advance(0.01)
        state = bridge.read()
    finally:
        bridge.close()
        ecu.stop()
        bridge_bus.shutdown()
        ecu_bus.shutdown()
    assert "command_timeout" in state.faults and state.mode == "standby"
    assert state.speed == 0.0 and plant.read().speed == 0.0


def test_realtime_clock_starts_at_engage_drives_and_times_out_on_the_wall_clock(channel):
    ecu_bus, bridge_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    ecu = EcuEmulator(ecu_bus, KinematicBicyclePlant(), clock=ClockMode.REALTIME)
    ecu.start()
    bridge = CanChassisBridge(bridge_bus, clock=ClockMode.REALTIME)
    try:
        time.sleep(0.4)  # set-up between construction and engage must not be replayed as a burst of steps
        bridge.engage()
        start = time.monotonic()
        assert bridge.time() < 0.1
        for _ in range(30):
            bridge.send(ChassisCommand(0.0, 2.0))
            bridge.advance(0.01)
        assert time.monotonic() - start == pytest.approx(0.3, abs=0.15)
        time.sleep(0.05)
        moving = bridge.read()
        assert moving.mode == "self-driving" and moving.speed > 0.2
        bridge.close()  # the 50 Hz sender stops
        time.sleep(0.4)
        assert ecu.command_timeout
    finally:
        ecu.stop()
        bridge_bus.shutdown()
        ecu_bus.shutdown()


def test_second_node_on_command_ids_is_detected_by_bridge_and_ecu(link, channel):
    bridge, ecu, _ = link
    bridge.engage()
    intruder_bus = can.Bus(interface="virtual", channel=channel)
    codec = ChassisCodec()
    try:
        for _ in range(20):
            request = ActuatorRequest.from_command(ChassisCommand(0.3, 3.0), enable=True, steer_rate=1.0)
            for name, signals in request.to_signals().items():
                intruder_bus.send(codec.encode(name, signals))
            bridge.send(ChassisCommand(0.0, 0.5))
            bridge.advance(0.01)
    finally:
        intruder_bus.shutdown()
    state = bridge.read()
    assert bridge.foreign_node and "foreign_node" in state.faults
    assert ecu.guard.foreign_node and state.mode == "standby"


@pytest.mark.parametrize("suffix", [".asc", ".blf"])
def test_every_frame_is_recorded_and_replays_onto_a_bus(link, tmp_path, suffix):
    bridge, _, _ = link
    recorder = FrameRecorder(tmp_path / f"run{suffix}")
    bridge.add_listener(recorder)
    bridge.engage()
    for _ in range(100):  # 1 s: commands and reports every 20 ms, step requests every 10 ms
        bridge.send(ChassisCommand(0.01, 1.0))
        bridge.advance(0.01)
    bridge.close()
    recorder.stop()
    assert recorder.frames == bridge.frames_tx + bridge.frames_rx > 500
    with can.LogReader(str(recorder.path)) as reader:
        logged = list(reader)
    assert len(logged) == recorder.frames
    assert {f.arbitration_id for f in logged} >= {0x130, 0x131, 0x132, 0x530, 0x534, 0x537}
    sink_channel = f"replay-{suffix}-{id(tmp_path)}"
    sender, sink = (can.Bus(interface="virtual", channel=sink_channel) for _ in range(2))
    try:
        assert replay_log(recorder.path, sender, realtime=False) == recorder.frames
        received = 0
        while sink.recv(0.01) is not None:
            received += 1
    finally:
        sender.shutdown()
        sink.shutdown()
    assert received == recorder.frames
