"""Faults stop the car and the run says so: each fault drill on a parking-lot run over the virtual bus brakes to
standstill in lane, ends as chassis_fault with the fault in summary.json, and still writes every output; the
command line exits non-zero with one line; commands never carry non-finite or out-of-range values; a stalled
loop stops the commands so the chassis times out; control is handed back only at standstill."""

import json
import math
import time
import uuid

import can
import numpy as np
import pytest

from hil.emulator.ecu import EcuEmulator
from hil.emulator.fault_drill import EXPECTED, run_drill
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.bridge import BridgeError, CanChassisBridge
from hil.link.codec import ChassisCodec
from hil.link.profile import load_profile
from hil.link.timing import ClockMode
from testbed.chassis import ChassisCommand
from testbed.cli import main
from testbed.eval.run.outputs import read_trajectory
from testbed.eval.run.scenario import load_scenario

AT = 1.5
CYCLE = 0.02
FAULT_DECEL = 4.0
OUTPUTS = {"summary.json", "trajectory.csv", "birdseye.png", "can.asc"}
# chassis time from injection to the latched fault: the next report set, or the report time-out
LATENCY_BOUND = {"report_timeout": 0.1 + 2 * CYCLE}


def parking_lot(seconds: float = 5.0):
    return load_scenario("parking-lot").with_overrides(duration=seconds, seed=1)


@pytest.mark.parametrize("drill", sorted(EXPECTED))
def test_each_fault_brakes_to_standstill_in_lane_and_ends_the_run_as_chassis_fault(drill, tmp_path):
    # the time bound is the fault path's: at the default 80 Hz physics the tyres creep near standstill and add about
    # 0.05 s to the last 0.1 m/s (docs/decisions.md, the physics rate), so the drill runs on 100 Hz physics
    sc = parking_lot()
    result = run_drill(sc.with_overrides(rates={**sc.rates.model_dump(), "physics_hz": 100.0}), drill, tmp_path, at=AT)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["consequence"] == "chassis_fault"
    assert result.detected == EXPECTED[drill]
    first = summary["faults"][0]
    assert set(first) == {"kind", "source", "time", "detail"} and first["source"] == "chassis" and first["detail"]
    assert 0.0 <= result.detection_latency_s <= LATENCY_BOUND.get(drill, 2 * CYCLE)
    track = read_trajectory(tmp_path, ["t", "speed"])
    speed_at_fault = float(np.interp(result.detected_s, track["t"], track["speed"]))
    assert speed_at_fault > 1.0  # the car was moving
    assert result.standstill_s is not None
    period = 1.0 / summary["resolved_scenario"]["rates"]["control_hz"]
    # braking at FAULT_DECEL from the speed at the fault; the loop brakes from the tick after the fault latched and
    # sees standstill at a tick (a control period each), and the brake ramps in and the speed tails off (0.08 s)
    assert 0.0 < result.standstill_s - result.detected_s <= speed_at_fault / FAULT_DECEL + 2 * period + 0.08
    assert abs(summary["final_dev_m"]) < 0.1  # stopped in its lane
    assert set(result.outputs) >= OUTPUTS
    with can.LogReader(str(tmp_path / "can.asc")) as reader:
        assert sum(1 for _ in reader) == summary["can_frames_logged"] > 0


def test_pix_hooke_chassis_estop_and_lost_reports_stop_the_run(tmp_path):
    for drill in ("chassis_estop", "report_timeout"):
        result = run_drill(parking_lot(), drill, tmp_path / drill, at=AT, profile="pix-hooke")
        assert result.summary["profile"] == "pix-hooke" and result.summary["consequence"] == "chassis_fault"
        assert result.detected == drill and result.standstill_s is not None


def test_command_line_fault_exits_3_with_one_line_and_writes_outputs(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["hil", "parking-lot", "--duration", "4", "--drill", "ecu_lost@1.5", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 3
    assert err.startswith("ld3: chassis fault: ecu_lost at 1.5") and "\n" not in err
    assert {p.name for p in out.iterdir()} >= OUTPUTS


@pytest.mark.parametrize(
    "argv",
    [
        ["hil", "parking-lot", "--interface", "socketcan", "--channel", "can0"],
        ["hil", "parking-lot", "--interface", "slcan", "--channel", "/dev/nonexistent"],
        ["ecu", "--interface", "socketcan", "--channel", "can0", "--duration", "0.1"],
        ["hil", "replay", "frames.asc", "--interface", "socketcan", "--channel", "can0", "--yes"],
    ],
)
def test_hardware_path_errors_are_one_line_and_exit_4(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "frames.asc").write_text("")
    code = main([*argv, "--out", str(tmp_path / "out")] if argv[0] == "hil" and argv[1] != "replay" else argv)
    err = capsys.readouterr().err.strip()
    assert code == 4 and err.startswith("ld3: CAN link error:") and "\n" not in err and "Traceback" not in err


def test_replay_refuses_a_hardware_bus_without_yes(capsys):
    assert main(["hil", "replay", __file__, "--interface", "socketcan", "--channel", "can0"]) == 2
    assert "--yes" in capsys.readouterr().err


def _link(profile_name: str, clock: ClockMode = ClockMode.LOCKSTEP):
    channel = f"hil-fault-{uuid.uuid4().hex}"
    profile = load_profile(profile_name)
    ecu_bus, bridge_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    ecu = EcuEmulator(ecu_bus, KinematicBicyclePlant(), clock=clock, profile=profile)
    ecu.start()
    bridge = CanChassisBridge(bridge_bus, clock=clock, profile=profile)
    spy = can.Bus(interface="virtual", channel=channel)

    def close() -> None:
        bridge.close()
        ecu.stop()
        for bus in (ecu_bus, bridge_bus, spy):
            bus.shutdown()

    return bridge, ecu, spy, close


def _drained(spy: can.BusABC) -> list[can.Message]:
    frames = []
    while (frame := spy.recv(0.0)) is not None:
        frames.append(frame)
    return frames


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_commands_never_reach_the_wire_and_brake(bad):
    bridge, _, spy, close = _link("pix-hooke")
    try:
        bridge.engage()
        _drained(spy)
        bridge.send(ChassisCommand(0.05, bad))
        bridge.advance(CYCLE)
        frames = [f for f in _drained(spy) if f.arbitration_id in (0x130, 0x131)]
    finally:
        close()
    codec = ChassisCodec(load_profile("pix-hooke"))
    decoded = {f.arbitration_id: codec.decode(f).signals for f in frames}
    assert decoded[0x130]["ChassisThrottlePdlTarget"] == 0.0  # +inf is not 100 % throttle
    assert decoded[0x131]["ChassisBrakePdlTarget"] == pytest.approx(FAULT_DECEL / 8.0 * 100.0)
    assert bridge.latched_faults()[0].kind == "bad_command"


def test_out_of_range_commands_are_clamped_to_the_profile_limits():
    bridge, _, spy, close = _link("pix-hooke")
    try:
        bridge.engage()
        _drained(spy)
        bridge.send(ChassisCommand(2.0, 50.0))
        bridge.advance(CYCLE)
        frames = {f.arbitration_id: bytes(f.data) for f in _drained(spy)}
    finally:
        close()
    assert int.from_bytes(frames[0x130][3:5], "little") & 0x3FF == 700  # 3.5 m/s² of 5 at 0.1 %: 70 %
    assert int.from_bytes(frames[0x132][1:3], "little", signed=True) == -450  # 30° left = 15 * 30°, + right
    assert not bridge.latched_faults()


def test_hand_back_only_at_standstill():
    bridge, ecu, _, close = _link("ld3-dev")
    try:
        bridge.engage()
        for _ in range(100):
            bridge.send(ChassisCommand(0.0, 2.0))
            bridge.advance(0.01)
        with pytest.raises(BridgeError, match="not at standstill"):
            bridge.release()
        assert ecu.mode.name == "SELF_DRIVING"
        bridge.stop_and_release()
        assert abs(ecu.plant.read().speed) < 0.05 and ecu.mode.name == "STANDBY"
    finally:
        close()


def test_a_stalled_loop_stops_the_commands_and_the_chassis_times_out_in_realtime():
    """In realtime the last command stands one control period and one cycle (10 + 20 ms here), then no more."""
    bridge, ecu, spy, close = _link("pix-hooke", ClockMode.REALTIME)
    try:
        bridge.engage()
        for _ in range(50):
            bridge.send(ChassisCommand(0.0, 2.0))
            bridge.advance(0.01)
        last_given = time.time()
        assert ecu.plant.read().speed > 0.3
        _drained(spy)
        stalled = time.monotonic()
        time.sleep(0.4)  # the loop stalls: no send, no advance
        sent_while_stalled = [f for f in _drained(spy) if f.arbitration_id in (0x130, 0x131, 0x132)]
        timed_out = ecu.command_timeout
        bridge.advance(0.01)
        state = bridge.read()
    finally:
        close()
    # the command's 30 ms life spans at most two cycle boundaries; a pacer woken late for the first sends it after
    # the drain, so up to two cycles of the three commands can follow it, each still inside that life
    assert len(sent_while_stalled) <= 6 and timed_out
    assert all(f.timestamp - last_given < 0.01 + 0.02 for f in sent_while_stalled)
    assert time.monotonic() - stalled >= 0.4
    assert "chassis_estop" in [f.kind for f in bridge.latched_faults()] and state.mode == "standby"


@pytest.mark.parametrize("name", ["pix-hooke", "ld3-dev"])
def test_realtime_chassis_estop_is_latched_within_the_period_of_its_report(name):
    # pix-hooke reports the e-stop in the work status, every 200 ms as PIX's DBC says; ld3-dev every 20 ms
    bridge, ecu, _, close = _link(name, ClockMode.REALTIME)
    try:
        bridge.engage()
        for _ in range(20):
            bridge.send(ChassisCommand(0.0, 1.0))
            bridge.advance(0.01)
        pressed = time.monotonic()
        ecu.press_estop()
        while not bridge.latched_faults() and time.monotonic() - pressed < 1.0:
            bridge.send(ChassisCommand(0.0, 1.0))
            bridge.advance(0.01)
        latency = time.monotonic() - pressed
    finally:
        close()
    profile = load_profile(name)
    assert bridge.latched_faults()[0].kind == "chassis_estop"
    assert latency <= profile.report_cycle_s(profile.reports.quantities["estop"].message) + 2 * CYCLE
