"""The `ld3 hil` / `ld3 ecu` commands: outputs of a short run, replay of its log, one-line user errors."""

import json
import time

import can
import pytest

from hil.cli import ecu_main, resolve_plant, result_line
from hil.emulator.plants import pybullet_plant
from testbed.cli import main


def test_ld3_hil_writes_the_outputs_and_its_log_replays_onto_a_bus(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["hil", "parking-lot", "--duration", "0.5", "--seed", "2", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seed"] == 2 and summary["interface"] == "virtual"
    assert "over virtual (lockstep): on the emulated plant's pose: consequence" in capsys.readouterr().out

    with can.LogReader(str(out / "can.asc")) as reader:
        logged = list(reader)
    commands = [f for f in logged if f.arbitration_id in (0x130, 0x131, 0x132)]
    span = logged[-1].timestamp - logged[0].timestamp
    assert len(logged) == summary["can_frames_logged"] and span >= 0.5  # plant time, not wall time

    listener_bus = can.Bus(interface="virtual", channel="hil-cli-replay")
    try:
        start = time.monotonic()
        assert main(["hil", "replay", str(out / "can.asc"), "--channel", "hil-cli-replay"]) == 0
        elapsed = time.monotonic() - start
        received = []
        while (frame := listener_bus.recv(0.0)) is not None:
            received.append(frame)
        assert main(["hil", "replay", str(out / "can.asc"), "--channel", "hil-cli-replay", "--ids", "all"]) == 0
        everything = 0
        while listener_bus.recv(0.0) is not None:
            everything += 1
    finally:
        listener_bus.shutdown()
    assert len(received) == len(commands) > 0  # only the command IDs by default
    assert [bytes(f.data) for f in received] == [bytes(f.data) for f in commands]
    assert elapsed >= 0.9 * (commands[-1].timestamp - commands[0].timestamp)  # paced by the log's time
    assert everything == summary["can_frames_logged"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["hil", "replay", "/nonexistent/frames.asc"], "CAN log not found"),
        (["hil", "replay"], "needs the log file"),
        (["hil", "parking-lot", "--log", "frames.txt", "--out", "/nonexistent/out"], "must end in .asc or .blf"),
        (["hil", "parking-lot", "--interface", "socketcan"], "socketcan needs --channel"),
        (["hil", "no-such-scenario"], "unknown scenario"),
        (["ecu", "--plant", "no_such_module:factory"], "cannot load plant"),
        (["ecu", "--plant-arg", "novalue"], "KEY=VALUE"),
    ],
)
def test_user_errors_are_one_line_and_exit_2(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("ld3: error:") and message in err and "\n" not in err


def test_the_result_line_names_the_pose_it_judges_on_and_odometry_s_own_beside_a_plant_s():
    summary = {"consequence": "hit_curb", "max_abs_dev_m": 0.615, "odometry_max_abs_dev_m": 0.02}
    assert result_line({**summary, "consequence_basis": "plant"}) == (
        "on the emulated plant's pose: consequence hit_curb, max |D| 0.615 m (odometry's max |D| 0.020 m)")
    assert result_line({**summary, "consequence_basis": "odometry", "max_abs_dev_m": None}) == (
        "on the bridge's odometry: consequence hit_curb, max |D| n/a")


def test_pybullet_plant_is_named_by_its_short_name_and_ecu_runs_a_scenario_plant():
    assert resolve_plant("pybullet") is pybullet_plant
    assert ecu_main(["--scenario", "parking-lot", "--channel", "hil-cli-ecu", "--duration", "0.05"]) == 0
