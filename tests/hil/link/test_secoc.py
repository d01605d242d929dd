"""SecOC-style authentication (ld3-dev-secoc): the MAC against RFC 4493 and a hand-assembled frame, freshness
reconstruction and its window, replayed and bit-flipped frames rejected without moving the receiver's state,
rejections counted and faulted as other integrity rejections, the key rules and one-line errors of a
malformed [secoc] table."""

import shutil
import uuid

import can
import pytest

from hil.emulator.ecu import EcuEmulator
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.emulator.scenario_run import HilLink, LinkConfig, run_hil_scenario
from hil.link.actuator_map import ActuatorRequest
from hil.link.bridge import CanChassisBridge
from hil.link.codec import ChassisCodec, FrameRejected
from hil.link.profile import PROFILES_DIR, ProfileError, load_profile
from hil.link.report_map import DrivingMode, EStopSource
from hil.link.secoc import FreshnessMonitor, aes_cmac
from hil.link.secoc_key import SecocKeyError, link_key
from hil.link.timing import ClockMode
from testbed.chassis import ChassisCommand
from testbed.cli import main
from testbed.eval.run.scenario import load_scenario
from tests.hil.link.cmac_reference import RFC4493_EXAMPLES, RFC4493_KEY, RFC4493_SUBKEYS, cmac, subkeys

SECOC = load_profile("ld3-dev-secoc")
KEY = RFC4493_KEY
STEER = {"SteerEnable": 1, "SteerAngleSpeed": 57.3, "SteerAngleTarget": -12.346}


def codec() -> ChassisCodec:
    return ChassisCodec(SECOC, KEY)


def steer_frame(tx: ChassisCodec) -> can.Message:
    return tx.encode("ACU_SteerCtrl", STEER)


def rejection(rx: ChassisCodec, frame: can.Message) -> str:
    with pytest.raises(FrameRejected) as rejected:
        rx.decode(frame)
    return rejected.value.reason


def test_the_profile_test_key_is_rfc_4493s_and_the_cmac_matches_its_vectors():
    assert SECOC.secoc.test_key == KEY
    assert subkeys(KEY) == RFC4493_SUBKEYS
    for message, tag in RFC4493_EXAMPLES:
        assert cmac(KEY, message) == tag  # the reference written out from the RFC
        assert aes_cmac(KEY, message) == tag  # what the codec computes with


def test_steer_frame_bytes_and_mac_by_hand():
    frame = steer_frame(codec())
    # bit 0 enable, bits 1-15 rate 57.3 °/s / 0.02 = 2865: 1 | 2865 << 1 = 0x1663; bytes 2-3 the angle
    # -12.346° / 0.002 = -6173 = 0xE7E3; byte 4 freshness 1 (the first frame)
    assert bytes(frame.data[:5]) == bytes([0x63, 0x16, 0xE3, 0xE7, 0x01])
    mac_input = bytes.fromhex("0132" "6316e3e700000000" "0000000000000001")  # ID, bytes 4-7 zeroed, freshness 1
    tag = cmac(KEY, mac_input)
    assert bytes(frame.data[5:]) == bytes([tag[2], tag[1], tag[0]])  # leading 24 bits, little-endian signal


def test_every_command_and_report_frame_is_secured_in_bytes_4_to_7():
    chassis = [m for m in SECOC.db.messages if m.name.startswith(("ACU_", "VCU_"))]
    assert {m.frame_id for m in chassis} == {0x130, 0x131, 0x132, 0x530, 0x531, 0x532, 0x533, 0x534, 0x537, 0x538}
    assert set(SECOC.secoc.messages) == {m.name for m in chassis}
    for message in chassis:
        fields = SECOC.secoc.messages[message.name]
        for signal in message.signals:
            span = {fields.freshness: (32, 8), fields.mac: (40, 24)}.get(signal.name)
            if span is None:
                assert signal.start + signal.length <= 32, signal.name  # payload in bytes 0-3
            else:
                assert (signal.start, signal.length) == span
    assert set(SECOC.integrity) == {m.name for m in SECOC.db.messages if m.name.startswith("SIM_")}


def test_freshness_reconstruction_and_window():
    monitor = FreshnessMonitor(bits=8, window=8)
    monitor.last = 0x1FE
    assert monitor.candidate(0xFF) == 0x1FF
    assert monitor.candidate(0x02) == 0x202  # across the wrap of the low byte
    assert monitor.candidate(0x06) == 0x206  # 8 newer: the edge of the window
    assert monitor.candidate(0x07) is None  # 9 newer
    assert monitor.candidate(0xFE) is None  # the last value again
    assert monitor.candidate(0xF0) is None  # older


def test_lost_frames_within_the_window_are_accepted_and_the_counter_wraps():
    tx, rx = codec(), codec()
    frames = [steer_frame(tx) for _ in range(300)]
    kept = frames[:250:8] + frames[250:]  # 7 lost between kept frames, then every frame across 256
    for frame in kept:
        rx.decode(frame)
    tx2, rx2 = codec(), codec()
    beyond = [steer_frame(tx2) for _ in range(9)][-1]  # 8 lost: 9 newer than the last accepted (0)
    assert rejection(rx2, beyond) == "freshness"


def test_replayed_and_delayed_frames_are_rejected_as_stale():
    tx, rx = codec(), codec()
    first, second, third = (steer_frame(tx) for _ in range(3))
    rx.decode(first)
    assert rejection(rx, first) == "freshness"  # the same frame again
    rx.decode(third)
    assert rejection(rx, second) == "freshness"  # overtaken
    assert rejection(rx, third) == "freshness"


@pytest.mark.parametrize("bit", [*range(32), *range(40, 64)])
def test_a_flipped_payload_or_mac_bit_is_rejected_and_changes_nothing(bit):
    tx, rx = codec(), codec()
    rx.decode(steer_frame(tx))
    genuine = steer_frame(tx)
    forged = can.Message(arbitration_id=genuine.arbitration_id, is_extended_id=False, data=bytearray(genuine.data))
    forged.data[bit // 8] ^= 1 << bit % 8
    assert rejection(rx, forged) == "mac"
    assert rx.decode(genuine).signals["SteerFreshness"] == 2  # the rejected frame did not move the freshness


def test_a_secured_profile_needs_its_key():
    with pytest.raises(ValueError, match="authenticates frames"):
        ChassisCodec(SECOC)
    assert rejection(ChassisCodec(SECOC, bytes(16)), steer_frame(codec())) == "mac"  # another key


def test_key_rules(monkeypatch, tmp_path):
    monkeypatch.delenv("LD3_SECOC_KEY", raising=False)
    assert link_key(SECOC, "virtual", None) == KEY
    assert link_key(SECOC, "slcan-pty", None) == KEY
    assert link_key(load_profile("ld3-dev"), "socketcan", "can0") is None
    for interface, channel in (("socketcan", "can0"), ("slcan", "/dev/ttyUSB0")):
        with pytest.raises(SecocKeyError, match=r"refusing its published test key.*set LD3_SECOC_KEY"):
            link_key(SECOC, interface, channel)
    monkeypatch.setenv("LD3_SECOC_KEY", "000102030405060708090a0b0c0d0e0f")
    assert link_key(SECOC, "socketcan", "can0") == bytes(range(16))
    assert link_key(SECOC, "virtual", None) == bytes(range(16))
    monkeypatch.setenv("LD3_SECOC_KEY", "0001")
    with pytest.raises(SecocKeyError, match="LD3_SECOC_KEY: expected 32 hex digits"):
        link_key(SECOC, "socketcan", "can0")


@pytest.mark.parametrize(
    "argv",
    [
        ["hil", "parking-lot", "--profile", "ld3-dev-secoc", "--interface", "socketcan", "--channel", "can0"],
        ["ecu", "--profile", "ld3-dev-secoc", "--interface", "socketcan", "--channel", "can0", "--duration", "0.1"],
    ],
)
def test_the_test_key_on_a_hardware_bus_is_one_line_naming_the_fix(argv, capsys, monkeypatch, tmp_path):
    monkeypatch.delenv("LD3_SECOC_KEY", raising=False)
    argv = [*argv, "--out", str(tmp_path / "out")] if argv[0] == "hil" else argv
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("ld3: error: profile ld3-dev-secoc: refusing its published test key on socketcan:can0")
    assert "set LD3_SECOC_KEY" in err and "\n" not in err


def test_rejected_commands_are_counted_and_a_run_of_them_revokes_control():
    bus = can.Bus(interface="virtual", channel=f"secoc-ecu-{uuid.uuid4().hex}")
    ecu = EcuEmulator(bus, KinematicBicyclePlant(), profile=SECOC, key=KEY)
    tx = codec()
    try:
        def cycle(enable: bool) -> dict[int, can.Message]:
            request = ActuatorRequest.from_command(ChassisCommand(0.0, 1.0), enable=enable, steer_rate=1.0)
            frames = {tx.frame_id(n): tx.encode(n, s) for n, s in request.to_signals(SECOC).items()}
            for frame in frames.values():
                ecu.handle(frame)
            ecu.step(0.02)
            return frames

        cycle(False)
        frames = cycle(True)
        assert ecu.mode is DrivingMode.SELF_DRIVING
        forged = bytearray(steer_frame(ChassisCodec(SECOC, bytes(16))).data)  # another key
        forged[4] = 3  # the next freshness value
        ecu.handle(frames[0x132])  # a replay
        ecu.handle(can.Message(arbitration_id=0x132, is_extended_id=False, data=forged))
        ecu.step(0.02)
        report = ecu.report()
        assert (report.bad_freshness_count, report.bad_mac_count) == (1, 1)
        assert not ecu.guard.bad_frames and ecu.mode is DrivingMode.SELF_DRIVING  # 2 in a row: no fault yet
        ecu.handle(can.Message(arbitration_id=0x132, is_extended_id=False, data=forged))  # the third
        ecu.step(0.02)
        assert ecu.guard.bad_frames and ecu.mode is DrivingMode.STANDBY
        assert ecu.report().estop is EStopSource.BAD_FRAMES
    finally:
        bus.shutdown()


def test_the_bridge_rejects_forged_reports_and_faults_on_a_run_of_them():
    bus = can.Bus(interface="virtual", channel=f"secoc-bridge-{uuid.uuid4().hex}")
    bridge = CanChassisBridge(bus, profile=SECOC, key=KEY)
    bridge.close()  # frames are fed by hand
    vcu, impostor = codec(), ChassisCodec(SECOC, bytes(16))
    try:
        bridge.handle(vcu.encode("VCU_DriveStatus", {"VehicleSpeed": 3.0}))
        impostor.encode("VCU_DriveStatus", {})  # a frame ahead: each forged frame below is fresh
        for _ in range(3):
            bridge.handle(impostor.encode("VCU_DriveStatus", {"VehicleSpeed": 9.0}))
    finally:
        bus.shutdown()
    assert bridge.frames_accepted == 1 and bridge.rejected["mac"] == 3
    assert bridge.read().speed == pytest.approx(3.0)
    assert [f.kind for f in bridge.latched_faults()] == ["bad_frames"]


class ForgedReports(can.Listener):
    """From chassis time `at`, three speed reports of 0 m/s carrying the next freshness values read off the
    bus and the last genuine MAC, sent while the bridge sends (before the next genuine report)."""

    def __init__(self, link: HilLink, at: float) -> None:
        self.link, self.at = link, at
        self.genuine: bytes | None = None
        self.sent = False

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_rx and msg.arbitration_id == 0x530:
            self.genuine = bytes(msg.data)
        if self.sent or msg.is_rx or self.genuine is None or self.link.bridge.time() < self.at:
            return
        self.sent = True
        intruder = can.Bus(interface="virtual", channel=self.link.channel)
        try:
            for k in range(1, 4):
                data = bytearray(self.genuine)
                data[2:4] = bytes(2)  # VehicleSpeed 0
                data[4] = (data[4] + k) % 256
                intruder.send(can.Message(arbitration_id=0x530, is_extended_id=False, data=data))
        finally:
            intruder.shutdown()


def test_forged_reports_during_a_run_stop_the_car_in_lane_as_a_chassis_fault():
    sc = load_scenario("parking-lot").with_overrides(duration=4.0, seed=1)
    forged: list[ForgedReports] = []

    def install(link: HilLink) -> None:
        forged.append(ForgedReports(link, 1.5))
        link.bridge.add_listener(forged[0])

    result = run_hil_scenario(sc, None, LinkConfig("virtual", profile="ld3-dev-secoc"), prepare=install)
    summary = result.summary
    assert forged[0].sent and summary["consequence"] == "chassis_fault"
    first = summary["faults"][0]
    assert first["kind"] == "bad_frames" and "mac" in first["detail"] and 1.5 <= first["time"] <= 1.52
    assert summary["can_frames_rejected"] == 3 and summary["stop_time_s"] is not None
    assert abs(summary["final_dev_m"]) < 0.1


@pytest.mark.parametrize("clock", [ClockMode.LOCKSTEP, ClockMode.REALTIME])
def test_a_secured_link_engages_drives_and_hands_back(clock):
    channel = f"secoc-link-{uuid.uuid4().hex}"
    ecu_bus, bridge_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    plant = KinematicBicyclePlant()
    ecu = EcuEmulator(ecu_bus, plant, clock=clock, profile=SECOC, key=KEY)
    ecu.start()
    bridge = CanChassisBridge(bridge_bus, clock=clock, profile=SECOC, key=KEY)
    try:
        bridge.engage()
        for _ in range(100):
            bridge.send(ChassisCommand(0.05, 1.0))
            bridge.advance(0.01)
        state = bridge.read()
        bridge.stop_and_release()
    finally:
        bridge.close()
        ecu.stop()
        bridge_bus.shutdown()
        ecu_bus.shutdown()
    assert state.mode == "self-driving" and state.speed > 0.7 and state.steer == pytest.approx(0.05, abs=0.002)
    assert not bridge.latched_faults() and sum(bridge.rejected.values()) == 0
    assert ecu.guard.admitted > 100 and sum(ecu.guard.rejected.values()) == 0
    assert plant.read().speed < 0.05 and ecu.mode is DrivingMode.STANDBY


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (("mac_bits = 24", "mac_bits = 128"), "secoc.mac_bits: must be 16 to 64"),
        (("mac_bits = 24", "mac_bits = 32"), "secoc.messages.ACU_DriveCtrl.mac: DriveMac must be"),
        (("freshness_window = 8", "freshness_window = 256"), "secoc.freshness_window: must be 1 to 255"),
        (('key_env = "LD3_SECOC_KEY"', 'key_env = ""'), "secoc.key_env"),
        (('key_env = "LD3_SECOC_KEY"', ""), "secoc.key_env: missing"),
        (('test_key = "2b7e', 'test_key = "zz7e'), "secoc.test_key: expected 32 hex digits"),
        (('mac = "SteerMac"', 'mac = "SteerAngleTarget"'), "secoc.messages.ACU_SteerCtrl.mac"),
        (('freshness = "WorkFreshness"', 'freshness = "NoSuchSignal"'), "secoc.messages.VCU_WorkStatus.freshness"),
        (("[secoc.messages]", '[secoc.messages]\nSIM_StepDone = { freshness = "A", mac = "B" }'),
         "secoc.messages.SIM_StepDone: also in [integrity]"),
        (("freshness_bits = 8", "freshness_bits = 8\nmac_len = 24"), "secoc.mac_len: unknown key"),
    ],
)
def test_malformed_secoc_table_is_a_one_line_error_naming_the_field(edit, field, tmp_path, capsys):
    root = tmp_path / "broken"
    shutil.copytree(PROFILES_DIR / "ld3-dev-secoc", root)
    text = (root / "profile.toml").read_text()
    assert edit[0] in text
    (root / "profile.toml").write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ProfileError, match=field.replace(".", r"\.").replace("[", r"\[").replace("]", r"\]")):
        load_profile(str(root))
    assert main(["hil", "parking-lot", "--profile", str(root), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("ld3: error: profile") and field in err and "\n" not in err
