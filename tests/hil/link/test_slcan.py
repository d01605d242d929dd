"""SLCAN on a pty: the device side against python-can's slcan interface, and the ECU in a separate process."""

import math
import threading

import can
import pytest

from hil.link.bridge import CanChassisBridge
from hil.link.bus_config import BusConfig
from hil.link.ecu_process import EcuProcess
from hil.link.slcan_pty import SlcanPtyBus
from tests.hil.link.driving import direct_run, run, start_odometry


def test_slcan_pty_carries_frames_both_ways_and_answers_protocol_commands():
    device = SlcanPtyBus()
    host = BusConfig("slcan", device.tty_path).open()
    try:
        host.send(can.Message(arbitration_id=0x130, is_extended_id=False, data=bytes(range(8))))
        host.send(can.Message(arbitration_id=0x1ABCDE, is_extended_id=True, data=b"\x01"))
        first, second = device.recv(1.0), device.recv(1.0)
        assert first.arbitration_id == 0x130 and bytes(first.data) == bytes(range(8))
        assert second.is_extended_id and second.arbitration_id == 0x1ABCDE and bytes(second.data) == b"\x01"
        payload = b"\xde\xad\xbe\xef\x00\x01\x02\x03"
        device.send(can.Message(arbitration_id=0x530, is_extended_id=False, data=payload))
        echoed = host.recv(1.0)
        assert echoed.arbitration_id == 0x530 and bytes(echoed.data) == payload
        answering = threading.Thread(target=device.recv, args=(0.5,))  # the adapter answers while it reads
        answering.start()
        assert host.get_version(1.0) == (10, 13)
        answering.join()
        host.serialPortOrig.write(b"t13G\r")  # malformed: the adapter answers BEL and drops it
        assert device.recv(0.2) is None and device.errors == 1
    finally:
        host.shutdown()
        device.shutdown()


def test_ecu_subprocess_over_slcan_matches_the_direct_run():
    process = EcuProcess(plant="tests.hil.link.driving:start_plant")
    bus = BusConfig("slcan", process.tty_path).open()
    bridge = CanChassisBridge(bus, reply_timeout=5.0, odometry=start_odometry())
    try:
        bridge.engage(timeout=5.0)
        assert bridge.read().mode == "self-driving"
        over_slcan = run(bridge, 300)
    finally:
        bridge.close()
        bus.shutdown()
        assert process.stop() == 0
    direct = direct_run(300)
    gaps = [math.hypot(a.x - b.x, a.y - b.y) for a, b in zip(over_slcan, direct, strict=True)]
    assert direct[-1].x > 4.0
    assert max(gaps) < 0.05
    assert sum(bridge.rejected.values()) == 0


def test_ecu_process_reports_a_bad_plant_spec():
    with pytest.raises(RuntimeError, match="did not start"):
        EcuProcess(plant="no_such_module:factory")
