"""pix-hooke equals PIX's public DBC (tests/hil/link/data/pixmoving.dbc, source and licence beside it): every message,
ID, signal, bit, scale, range, enum and cycle time, the steering scale of PIX's public driver, and the emulator
sending each report at the DBC's period."""

import math
import uuid
from pathlib import Path

import can
import cantools
import pytest

from hil.emulator.ecu import EcuEmulator
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.bridge import CanChassisBridge
from hil.link.profile import load_profile
from testbed.chassis import ChassisCommand

PUBLIC = cantools.database.load_file(str(Path(__file__).parent / "data" / "pixmoving.dbc"), encoding="utf-8",
                                     strict=True)
PIX = load_profile("pix-hooke")
# the profile's DBC is read as cp1252, which has no ℃ and no Chinese: these two are written in ASCII
UNITS = {"℃": "degC"}
LABELS = {"Unknow(传感器故障)": "Unknow(sensor fault)"}


def _signal(s: cantools.database.can.Signal) -> tuple:
    choices = {int(k): LABELS.get(str(v), str(v)) for k, v in (s.choices or {}).items()}
    return (s.start, s.length, s.byte_order, s.is_signed, s.scale, s.offset, s.minimum, s.maximum,
            UNITS.get(s.unit or "", s.unit or ""), choices, s.is_multiplexer, s.multiplexer_ids)


def _message(m: cantools.database.can.Message) -> tuple:
    return (m.frame_id, m.is_extended_frame, m.length, tuple(m.senders), m.cycle_time, m.send_type)


@pytest.mark.parametrize("name", sorted(m.name for m in PUBLIC.messages))
def test_each_public_message_is_in_the_profile_with_the_same_id_period_and_signals(name):
    public, ours = PUBLIC.get_message_by_name(name), PIX.db.get_message_by_name(name)
    assert _message(ours) == _message(public)
    assert {s.name: _signal(s) for s in ours.signals} == {s.name: _signal(s) for s in public.signals}


def test_the_profile_adds_only_the_emulator_frames():
    sim = PIX.simulation
    extra = {m.name for m in PIX.db.messages} - {m.name for m in PUBLIC.messages}
    assert extra == {sim.step_request, sim.step_done, sim.truth_position, sim.truth_motion}
    assert not {PIX.frame_id(n) for n in extra} & {m.frame_id for m in PUBLIC.messages}


def test_the_facts_a_chassis_engineer_checks_first():
    brake_status = PIX.db.get_message_by_name("BrakeStaFb")
    assert brake_status.get_signal_by_name("AebTriggerStaFb").start == 26
    steer = PIX.db.get_message_by_name(PIX.commands.steer)
    assert PIX.integrity[PIX.commands.steer].counter is None  # the public steer command has no life counter
    assert all("life" not in s.name.lower() for s in steer.signals)
    assert PIX.report_cycle_s(PIX.reports.quantities["mode"].message) == 0.2  # work status 0x534
    assert PIX.report_cycle_s(PIX.reports.faults["steer_fault"].message) == 0.2  # fault status 0x537
    assert PIX.report_cycle_s(PIX.reports.quantities["speed"].message) == 0.02
    assert PIX.secoc is None
    # PIX's driver: wire = 450 / max_steering_angle (0.5236 rad) * road-wheel angle, + right on the wire
    assert PIX.steering.to_wire(-0.5236) == pytest.approx(450.0, abs=0.01)
    assert PIX.steering.to_wire(PIX.steering.max_angle) == pytest.approx(-450.0)


def test_the_emulator_sends_each_report_at_the_public_period():
    channel = f"pix-periods-{uuid.uuid4().hex}"
    ecu_bus, bridge_bus, spy = (can.Bus(interface="virtual", channel=channel) for _ in range(3))
    ecu = EcuEmulator(ecu_bus, KinematicBicyclePlant(), profile=PIX)
    ecu.start()
    bridge = CanChassisBridge(bridge_bus, profile=PIX)
    try:
        bridge.engage()
        while spy.recv(0.0) is not None:
            pass
        for _ in range(100):  # 2 s of chassis time in 20 ms ticks
            bridge.send(ChassisCommand(0.0, 0.5))
            bridge.advance(0.02)
        frames = []
        while (frame := spy.recv(0.0)) is not None:
            frames.append(frame)
    finally:
        bridge.close()
        ecu.stop()
        for bus in (ecu_bus, bridge_bus, spy):
            bus.shutdown()
    counts = {i: sum(1 for f in frames if f.arbitration_id == i) for i in (0x530, 0x531, 0x532, 0x534, 0x537)}
    assert counts == {0x530: 100, 0x531: 100, 0x532: 100, 0x534: 10, 0x537: 10}
    assert not bridge.latched_faults() and math.isclose(bridge.time(), 2.0)
