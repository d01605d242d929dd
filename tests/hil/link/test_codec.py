"""Codec, integrity and actuator mapping: round trips, checksum and life-counter checks, quantisation."""

import math

import can
import pytest

from hil.link.actuator_map import ActuatorRequest, Gear
from hil.link.codec import ChassisCodec, FrameRejected
from hil.link.integrity import LifeMonitor, LifeVerdict, checksum_ok, xor_checksum
from hil.link.profile import default_profile
from testbed.chassis import ChassisCommand


def test_xor_checksum_and_life_monitor():
    data = bytes([1, 2, 4, 8, 16, 32, 64, 0])
    assert xor_checksum(data) == 127
    assert checksum_ok(data[:7] + bytes([127])) and not checksum_ok(data)
    monitor = LifeMonitor()
    assert [monitor.check(v) for v in (14, 15, 0, 0, 5, 6)] == [
        LifeVerdict.OK,
        LifeVerdict.OK,
        LifeVerdict.OK,
        LifeVerdict.STALE,
        LifeVerdict.SKIPPED,
        LifeVerdict.OK,
    ]


def test_encode_fills_life_counter_and_checksum_and_decode_round_trips():
    tx, rx = ChassisCodec(), ChassisCodec()
    for k in range(20):
        signals = {"SteerEnable": 1, "SteerAngleTarget": -12.346, "SteerAngleSpeed": 57.3}
        frame = tx.encode("ACU_SteerCtrl", signals)
        assert frame.data[6] & 0x0F == k % 16
        assert frame.data[7] == xor_checksum(frame.data)
        decoded = rx.decode(frame)
        assert decoded.signals["SteerAngleTarget"] == pytest.approx(-12.346, abs=0.001)
        assert decoded.signals["SteerLife"] == k % 16


def test_decode_rejects_bad_checksum_stale_counter_format_and_range():
    tx, rx = ChassisCodec(), ChassisCodec()
    signals = {"DriveEnable": 1, "DriveGearTarget": 4, "DriveThrottlePct": 10.0}
    first = tx.encode("ACU_DriveCtrl", signals)
    rx.decode(first)
    with pytest.raises(FrameRejected) as stale:
        rx.decode(first)
    assert stale.value.reason == "counter"
    corrupt = tx.encode("ACU_DriveCtrl", signals)
    corrupt.data[2] ^= 0x01
    with pytest.raises(FrameRejected) as bad_sum:
        rx.decode(corrupt)
    assert bad_sum.value.reason == "checksum"
    short = can.Message(arbitration_id=0x130, is_extended_id=False, dlc=7, data=bytes(7))
    with pytest.raises(FrameRejected) as bad_format:
        rx.decode(short)
    assert bad_format.value.reason == "format"
    over = bytearray(tx.encode("ACU_DriveCtrl", signals).data)
    over[2:4] = (10001).to_bytes(2, "little")  # 100.01 %
    over[7] = xor_checksum(over)
    with pytest.raises(FrameRejected) as bad_range:
        rx.decode(can.Message(arbitration_id=0x130, is_extended_id=False, data=over))
    assert bad_range.value.reason == "range"


@pytest.mark.parametrize("accel", [-9.0, -4.0, -0.0123, 0.0, 0.0007, 1.2345, 4.9])
@pytest.mark.parametrize("steer", [-0.5, -0.01234, 0.0, 0.3])
def test_command_cycle_survives_the_wire_within_its_resolution(accel, steer):
    tx, rx = ChassisCodec(), ChassisCodec()
    request = ActuatorRequest.from_command(ChassisCommand(steer, accel), enable=True, steer_rate=1.0)
    frames = {name: rx.decode(tx.encode(name, s)).signals for name, s in request.to_signals().items()}
    back = ActuatorRequest.from_signals(*(frames[name] for name in default_profile().commands.messages))
    assert back.enable and back.gear is Gear.DRIVE
    assert back.accel == pytest.approx(max(accel, -default_profile().longitudinal.full_brake_decel), abs=0.0005)
    assert back.steer == pytest.approx(steer, abs=math.radians(0.001) + 1e-12)
    assert back.steer_rate == pytest.approx(1.0, abs=1e-3)
