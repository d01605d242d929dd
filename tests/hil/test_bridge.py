"""Bridge over the virtual bus: handshake, agreement with the direct run, faults surfaced, foreign node, recording."""

import math

import can
import pytest

from hil.actuator_map import ActuatorRequest
from hil.bridge import CanChassisBridge
from hil.codec import ChassisCodec
from hil.ecu import EcuEmulator, EcuLimits
from hil.kinematic_plant import KinematicBicyclePlant
from hil.recorder import FrameRecorder
from hil.replay import replay_log
from testbed.chassis import ChassisCommand
from tests.hil.conftest import SampleAndHoldPort
from tracks.pose import Pose

START = Pose(0.0, 0.8, 0.05)


def lane_keeper(state):
    """Speed to 4 m/s and hold y = 0, with a gentle weave so the steering keeps moving."""
    pose = state.true_pose
    steer = -0.3 * pose.y - 0.8 * math.remainder(pose.yaw, math.tau) + 0.01 * math.sin(0.7 * state.t)
    return ChassisCommand(max(min(steer, 0.4), -0.4), max(min(1.5 * (4.0 - state.speed), 3.0), -4.0))


def run(port, ticks):
    poses = []
    for _ in range(ticks):
        state = port.read()
        poses.append(state.true_pose)
        port.send(lane_keeper(state))
        port.advance(0.01)
    return poses


def direct_run(ticks):
    return run(SampleAndHoldPort(KinematicBicyclePlant(pose=START)), ticks)


def test_engage_reports_standby_then_self_driving(link):
    bridge, ecu, _ = link
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
    bridge = CanChassisBridge(bridge_bus, steer_rate=5.0)
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


def test_command_stop_surfaces_timeout_fault_and_standstill_in_state(link):
    bridge, ecu, plant = link
    bridge.engage()
    for _ in range(200):
        bridge.send(ChassisCommand(0.0, 2.0))
        bridge.advance(0.01)
    assert bridge.read().speed > 3.0
    bridge.send = lambda cmd: None  # the host keeps stepping but its commands never change...
    ecu.guard.command_ids = frozenset()  # ...and the VCU hears none of them from now on
    for _ in range(200):
        bridge.advance(0.01)
    state = bridge.read()
    assert "command_timeout" in state.faults and state.mode == "standby"
    assert state.speed == 0.0 and plant.read().speed == 0.0


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
    bridge, ecu, _ = link
    recorder = FrameRecorder(tmp_path / f"run{suffix}")
    bridge.add_listener(recorder)
    bridge.engage()
    for _ in range(50):
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
