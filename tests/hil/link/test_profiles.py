"""Chassis profiles: the pix-hooke command bytes against the public layout (hand-computed), the shipped and a
user's own profile driving the link, and one-line errors naming the field of a malformed profile."""

import math
import shutil
import uuid

import can
import pytest

from hil.emulator.ecu import EcuEmulator
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.actuator_map import ActuatorRequest
from hil.link.bridge import CanChassisBridge
from hil.link.codec import ChassisCodec
from hil.link.profile import PROFILES_DIR, ProfileError, load_profile
from testbed.chassis import ChassisCommand
from testbed.cli import main

PIX = load_profile("pix-hooke")


def pix_frames(steer: float, accel: float, steer_rate: float = 0.5) -> dict[int, bytes]:
    codec = ChassisCodec(PIX)
    request = ActuatorRequest.from_command(ChassisCommand(steer, accel), enable=True, steer_rate=steer_rate)
    return {codec.frame_id(n): bytes(codec.encode(n, s).data) for n, s in request.to_signals(PIX).items()}


def test_pix_hooke_drive_frame_bytes():
    # 0x130: enable bit 0, throttle mode 1 in bits 2-3, gear D = 1 in bits 4-7 -> 0x15; speed target 0;
    # throttle 1.0 / 5.0 m/s² = 20.0 % = 200 at 0.1 % in bits 24-33; life 0 in bits 48-51; byte 7 XOR
    assert pix_frames(0.0, 1.0)[0x130] == bytes([0x15, 0x00, 0x00, 0xC8, 0x00, 0x00, 0x00, 0xDD])


def test_pix_hooke_brake_frame_bytes():
    # 0x131: enable bit 0; pedal 2.0 / 8.0 m/s² = 25.0 % = 250 = 0xFA in bits 8-17; byte 7 = 0x01 ^ 0xFA
    frames = pix_frames(0.0, -2.0)
    assert frames[0x131] == bytes([0x01, 0xFA, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFB])
    assert frames[0x130][3] == 0x00 and frames[0x130][4] & 0x03 == 0  # no throttle while braking


def test_pix_hooke_steer_frame_bytes():
    # 0x132: 5° road wheel left = -75° at the steering wheel (ratio 15, + right) = 0xFFB5 in bits 8-23;
    # rate 0.5 rad/s = 28.65 °/s road wheel = 429.7 °/s at the wheel = 215 at 2 °/s in bits 40-47;
    # no life counter (byte 6 stays 0); byte 7 XOR
    frame = pix_frames(math.radians(5.0), 0.0)[0x132]
    assert frame == bytes([0x01, 0xB5, 0xFF, 0x00, 0x00, 0xD7, 0x00, 0x9C])


def test_pix_hooke_life_counters_advance_per_frame_and_reports_need_no_checksum():
    codec = ChassisCodec(PIX)
    request = ActuatorRequest.from_command(ChassisCommand(0.0, 0.0), enable=True, steer_rate=0.5)
    lives = [codec.encode("DriveCtrl", request.to_signals(PIX)["DriveCtrl"]).data[6] & 0x0F for _ in range(18)]
    assert lives == [k % 16 for k in range(18)]
    steer = [codec.encode("SteerCtrl", request.to_signals(PIX)["SteerCtrl"]).data[6] for _ in range(3)]
    assert steer == [0, 0, 0]  # the public steer command carries no life counter
    speed_report = bytearray(8)
    speed_report[1:3] = (412).to_bytes(2, "little")  # 4.12 m/s, byte 7 left 0: no checksum on 0x530
    decoded = ChassisCodec(PIX).decode(can.Message(arbitration_id=0x530, is_extended_id=False, data=speed_report))
    assert decoded.signals["ChassisSpeedFb"] == pytest.approx(4.12)


@pytest.mark.parametrize("name", ["pix-hooke", "user"])
def test_a_profile_drives_the_link_with_no_code_change(name, tmp_path):
    if name == "user":  # a user's own chassis: a copied folder, renamed messages in DBC and profile
        root = tmp_path / "my-chassis"
        shutil.copytree(PROFILES_DIR / "pix-hooke", root)
        for file in ("chassis.dbc", "profile.toml"):
            path = root / file
            path.write_text(path.read_text().replace(" SteerCtrl", " MySteer").replace('"SteerCtrl"', '"MySteer"')
                            .replace("SteerCtrl =", "MySteer =").replace("pix-hooke", "mine"))
        profile = load_profile(str(root))
        assert profile.commands.steer == "MySteer"
    else:
        profile = load_profile(name)
    channel = f"hil-profile-{uuid.uuid4().hex}"
    ecu_bus, bridge_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    plant = KinematicBicyclePlant()
    ecu = EcuEmulator(ecu_bus, plant, profile=profile)
    ecu.start()
    bridge = CanChassisBridge(bridge_bus, profile=profile)
    try:
        bridge.engage()
        for _ in range(200):
            bridge.send(ChassisCommand(0.05, 1.0))
            bridge.advance(0.01)
        state, truth = bridge.read(), plant.read()
        bridge.stop_and_release()
    finally:
        bridge.close()
        ecu.stop()
        bridge_bus.shutdown()
        ecu_bus.shutdown()
    assert state.mode == "self-driving" and not bridge.latched_faults()
    assert state.speed == pytest.approx(truth.speed, abs=0.01) and state.speed > 1.5
    assert state.steer == pytest.approx(0.05, abs=0.002)
    assert sum(bridge.rejected.values()) == 0 and ecu.guard.admitted > 0
    assert truth.true_pose.x > 1.9  # it drove, and the odometry followed it from the reports alone
    assert math.hypot(state.true_pose.x - truth.true_pose.x, state.true_pose.y - truth.true_pose.y) < 0.01
    assert plant.read().speed < 0.05 and ecu.mode.name == "STANDBY"  # handed back at standstill


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (('angle = "ChassisSteerAngleTarget"', 'angle = "NoSuchSignal"'), "commands.steer.angle"),
        (("cycle_ms = 20\n", ""), "timing.cycle_ms: missing"),
        (("[gears]\n", "[gears]\nsecond = 5\n"), "gears.second: unknown name"),
        (('positive = "right"', 'positive = "up"'), "steering.positive"),
        (('"Life", checksum = "CheckSum"', '"Life", checksum = "Life"'), "checksum"),
        (("max_accel = 3.5", "max_accel = 30.5"), "longitudinal.max_accel"),
        (("[timing]\n", "[timing]\ncycle = 1\n"), "timing.cycle: unknown key"),
        (('speed = "DriveStaFb.ChassisSpeedFb"', 'speed = "ChassisSpeedFb"'), "reports.speed"),
        (("cycle_ms = 20", "cycle_ms = 0"), "timing.cycle_ms: must be > 0"),
        (("cycle_ms = 20", 'cycle_ms = "fast"'), "timing.cycle_ms: must be a number"),
        (("command_timeout_ms = 100", "command_timeout_ms = 10"), "timing.command_timeout_ms: shorter than one cycle"),
        (("ratio = 15.0", "ratio = nan"), "steering.ratio: must be finite"),
        (("[modes]\nstandby = 0\n", "[modes]\n"), "modes: needs standby"),
        (('speed = "DriveStaFb.ChassisSpeedFb"\n', ""), "reports.speed: missing"),
        (("[reports.estop_values]\nnone = 0\n", "[reports.estop_values]\n"), "reports.estop_values: needs 'none'"),
        (("constants = { ChassisDriverModeCtrl = 1 }", 'constants = { ChassisDriverModeCtrl = "one" }'),
         "commands.drive.constants.ChassisDriverModeCtrl: must be a number"),
    ],
)
def test_malformed_profile_is_a_one_line_error_naming_the_field(edit, field, tmp_path, capsys):
    root = tmp_path / "broken"
    shutil.copytree(PROFILES_DIR / "pix-hooke", root)
    text = (root / "profile.toml").read_text()
    assert edit[0] in text
    (root / "profile.toml").write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ProfileError, match=field.replace(".", r"\.")):
        load_profile(str(root))
    assert main(["hil", "parking-lot", "--profile", str(root), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("ld3: error: profile") and field in err and "\n" not in err


def test_unknown_profile_names_the_shipped_ones():
    with pytest.raises(ProfileError, match="ld3-dev, ld3-dev-secoc, pix-hooke"):
        load_profile("no-such-chassis")
