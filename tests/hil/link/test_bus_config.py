"""Any python-can interface carries the link: names come from python-can's registry, channel and bitrate from
the command line or python-can's configuration (environment, ~/.canrc sections) where it names the same
interface; a missing driver or device is one line naming the interface (exit 4); everything but the virtual bus
and SLCAN on a pty gets the hardware rules."""

from __future__ import annotations

import can
import pytest

from hil.emulator.scenario_run import LinkConfig
from hil.link.bus_config import BusConfig, BusOpenError, interfaces, parse_options
from hil.link.slcan_pty import SlcanPtyBus
from testbed.cli import main


@pytest.fixture(autouse=True)
def no_user_can_config(monkeypatch, tmp_path):
    for name in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.chdir(tmp_path)


def test_every_python_can_interface_is_accepted_and_unknown_names_are_refused():
    assert set(interfaces()) == set(can.interfaces.VALID_INTERFACES) >= {"pcan", "kvaser", "vector", "gs_usb"}
    for name in interfaces():
        assert BusConfig(name, "0").interface == name
    with pytest.raises(ValueError, match="unknown CAN interface 'pcann'; python-can knows"):
        BusConfig("pcann")


def test_channel_and_bitrate_come_from_python_can_configuration_for_the_same_interface(monkeypatch, tmp_path):
    monkeypatch.setenv("CAN_INTERFACE", "socketcan")
    monkeypatch.setenv("CAN_CHANNEL", "vcan7")
    assert BusConfig("socketcan").kwargs() == {"interface": "socketcan", "channel": "vcan7"}
    assert BusConfig("socketcan", "can1").kwargs()["channel"] == "can1"  # the command line wins
    assert BusConfig("pcan").kwargs() == {"interface": "pcan", "bitrate": 500_000}  # env names another interface
    monkeypatch.delenv("CAN_INTERFACE")
    monkeypatch.delenv("CAN_CHANNEL")
    (tmp_path / ".canrc").write_text("[chassis]\ninterface = kvaser\nchannel = 1\nbitrate = 250000\ndata_bitrate = "
                                     "2000000\n")
    kvaser = BusConfig("kvaser", context="chassis", options=parse_options(["fd=true"])).kwargs()
    assert kvaser == {"interface": "kvaser", "channel": 1, "bitrate": 250_000, "data_bitrate": 2_000_000, "fd": True}
    monkeypatch.setenv("CAN_INTERFACE", "pcan")
    monkeypatch.setenv("CAN_CHANNEL", "PCAN_USBBUS1")
    with pytest.raises(ValueError, match="socketcan needs --channel"):
        LinkConfig("socketcan")


def test_bad_options_are_user_errors():
    with pytest.raises(ValueError, match="KEY=VALUE"):
        parse_options(["fd"])


def test_hardware_rules_cover_every_interface_but_the_emulators():
    pty = SlcanPtyBus()
    try:
        assert not BusConfig("virtual").hardware and not BusConfig("slcan", pty.tty_path).hardware
    finally:
        pty.shutdown()
    for name in ("pcan", "kvaser", "gs_usb", "socketcan", "serial", "slcan"):
        assert BusConfig(name, "/dev/ttyUSB0" if name in ("serial", "slcan") else "0").hardware
    assert LinkConfig("pcan", "PCAN_USBBUS1").clock_mode.value == "realtime"
    assert LinkConfig("slcan").clock_mode.value == "lockstep"  # the ECU process on its own pty


def test_a_missing_driver_is_one_error_naming_the_interface_and_what_is_missing():
    with pytest.raises(BusOpenError, match=r"^interface kvaser: driver missing: Kvaser canlib is unavailable"):
        BusConfig("kvaser").open()
    with pytest.raises(BusOpenError, match=r"^interface gs_usb: driver missing: .*No module named"):
        BusConfig("gs_usb").open()


@pytest.mark.parametrize(
    ("argv", "line"),
    [
        (["--interface", "kvaser"], "ld3: CAN link error: interface kvaser: driver missing: Kvaser canlib"),
        (["--interface", "pcan"], "ld3: CAN link error: interface pcan: driver missing: pcanbasic library"),
        (["--interface", "serial", "--channel", "/dev/nonexistent"],
         "ld3: CAN link error: interface serial channel /dev/nonexistent: cannot open the device"),
    ],
)
def test_command_line_names_the_interface_and_exits_4(argv, line, capsys, tmp_path):
    assert main(["hil", "parking-lot", *argv, "--out", str(tmp_path / "out")]) == 4
    err = capsys.readouterr().err.strip()
    assert err.startswith(line) and "\n" not in err


def test_replay_and_the_secoc_test_key_refuse_any_hardware_interface(capsys, tmp_path):
    log = tmp_path / "frames.asc"
    log.write_text("")
    assert main(["hil", "replay", str(log), "--interface", "pcan", "--channel", "PCAN_USBBUS1"]) == 2
    assert "refusing to replay onto pcan:PCAN_USBBUS1" in capsys.readouterr().err
    assert main(["hil", "parking-lot", "--profile", "ld3-dev-secoc", "--interface", "kvaser", "--channel", "0"]) == 2
    assert "refusing its published test key on kvaser" in capsys.readouterr().err
