"""ECU emulator: handshake, command-timeout e-stop, frame rejection, bad-frame run, foreign node, limits."""

import math

import pytest

from hil.emulator.ecu import EcuLimits
from hil.link.report_map import DrivingMode, EStopSource
from testbed.chassis import ChassisCommand

DT = 0.01


def drive_to_speed(host, ecu, speed):
    host.cycle(ChassisCommand(0.0, 0.0), enable=False)
    host.step(0.0)
    host.cycle(ChassisCommand(0.0, 2.0))
    host.step(0.0)
    assert ecu.mode is DrivingMode.SELF_DRIVING
    k = 0
    while ecu.plant.read().speed < speed:
        if k % 2 == 0:
            host.cycle(ChassisCommand(0.0, 2.0))
        host.step(DT)
        k += 1
    return k


def test_handshake_from_standby_to_self_driving_and_release(sync_ecu):
    host, ecu, _ = sync_ecu
    assert ecu.mode is DrivingMode.STANDBY
    host.cycle(ChassisCommand(0.0, 0.0), enable=False)
    host.step(0.0)
    assert ecu.mode is DrivingMode.STANDBY
    host.cycle(ChassisCommand(0.0, 0.0), enable=True)
    host.step(0.0)
    assert ecu.mode is DrivingMode.SELF_DRIVING and ecu.report().enabled
    host.cycle(ChassisCommand(0.0, 0.0), enable=False)
    host.step(0.0)
    assert ecu.mode is DrivingMode.STANDBY


def test_command_timeout_brakes_to_standstill_and_reports_it(sync_ecu):
    host, ecu, plant = sync_ecu
    drive_to_speed(host, ecu, 4.0)
    last_command_t = ecu.now()
    host.step(DT)
    while not ecu.command_timeout:
        host.step(DT)
    assert ecu.now() - last_command_t == pytest.approx(0.1, abs=1e-9)
    report = ecu.report()
    assert report.estop is EStopSource.COMMAND_TIMEOUT and report.mode is DrivingMode.STANDBY
    v0 = plant.read().speed
    steps = 0
    while plant.read().speed > 0.0:
        host.step(DT)
        steps += 1
    assert steps * DT <= v0 / EcuLimits().estop_decel + 2 * DT
    assert ecu.report().command_timeout and ecu.report().speed == 0.0
    host.cycle(ChassisCommand(0.0, 1.0))  # enable without a release does not take control back
    host.step(DT)
    assert ecu.mode is DrivingMode.STANDBY and plant.read().speed == 0.0
    host.cycle(ChassisCommand(0.0, 0.0), enable=False)
    host.step(0.0)
    host.cycle(ChassisCommand(0.0, 1.0))
    host.step(DT)
    assert ecu.mode is DrivingMode.SELF_DRIVING and not ecu.command_timeout


def test_bad_checksum_and_stale_counter_frames_are_rejected_and_counted(sync_ecu):
    host, ecu, plant = sync_ecu
    drive_to_speed(host, ecu, 1.0)
    frames = host.cycle_frames(ChassisCommand(0.3, 0.0))
    frames[2].data[1] ^= 0xFF  # steer target corrupted: checksum no longer matches
    for frame in frames:
        ecu.handle(frame)
    host.step(DT)
    assert ecu.guard.rejected["checksum"] == 1
    assert plant.read().steer == 0.0
    host.cycle(ChassisCommand(0.0, 1.0))  # the steer frame skips the lost counter value: rejected once
    host.step(DT)
    replay = host.cycle_frames(ChassisCommand(0.0, 1.0))
    for frame in replay:
        ecu.handle(frame)
    host.step(DT)
    for frame in replay:
        ecu.handle(frame)  # the same frames again: stale life counters
    assert ecu.guard.rejected["counter"] == 4
    assert ecu.report().bad_counter_count == 4 and ecu.report().bad_checksum_count == 1
    assert not ecu.guard.bad_frames  # no run of 3 rejections on one ID


def test_run_of_bad_frames_revokes_control(sync_ecu):
    host, ecu, _ = sync_ecu
    drive_to_speed(host, ecu, 1.0)
    for _ in range(3):
        frame = host.cycle_frames(ChassisCommand(0.0, 1.0))[0]
        frame.data[7] ^= 0x55
        ecu.handle(frame)
    host.step(DT)
    assert ecu.guard.bad_frames and ecu.mode is DrivingMode.STANDBY
    assert ecu.report().estop is EStopSource.BAD_FRAMES


def test_second_node_on_command_ids_is_detected(sync_ecu):
    host, ecu, _ = sync_ecu
    drive_to_speed(host, ecu, 1.0)
    intruder = type(host)(ecu)  # its own codec: its own life counters
    for _ in range(10):
        host.cycle(ChassisCommand(0.0, 0.0))
        intruder.cycle(ChassisCommand(0.2, 3.0))
        host.step(DT)
        host.step(DT)
    assert ecu.guard.foreign_node
    report = ecu.report()
    assert report.foreign_node and report.estop in (EStopSource.BAD_FRAMES, EStopSource.FOREIGN_NODE)
    assert ecu.mode is DrivingMode.STANDBY


def test_steering_angle_and_rate_limits_are_enforced(sync_ecu):
    host, ecu, plant = sync_ecu
    limits = EcuLimits()
    drive_to_speed(host, ecu, 0.5)
    host.cycle(ChassisCommand(1.5, 0.0))
    host.step(DT)
    assert plant.read().steer == pytest.approx(limits.max_steer_rate * 0.02, abs=1e-4)
    assert ecu.report().steer_limited
    for _ in range(100):
        host.cycle(ChassisCommand(1.5, 0.0))
        host.step(DT)
        host.step(DT)
    assert plant.read().steer == pytest.approx(limits.max_steer, abs=1e-4)
    assert math.degrees(ecu.report().steer) < 35.0

