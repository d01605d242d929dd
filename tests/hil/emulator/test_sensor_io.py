"""Sensor-level HIL: GNSS as NMEA over a pty and camera frames through the camera reader drive the same run as
the simulated sensors (within 10 cm, same consequence, an attack still detected and stopped in lane); a GNSS
stream or a camera that stops ends the run as chassis_fault with its stall."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hil.emulator.scenario_run import run_hil_scenario
from testbed.cli import main
from testbed.eval.run.outputs import read_trajectory
from testbed.eval.run.scenario import load_scenario

ATTACKED = ["hil", "parking-lot", "--localization", "msf", "--speed", "4", "--duration", "12", "--attack",
            "trace:default,start=3", "--defense", "ld3"]


def test_io_sensors_drive_the_attacked_run_as_the_simulated_ones_do(tmp_path, capsys):
    for sensors in ("sim", "io"):
        assert main([*ATTACKED, "--sensors", sensors, "--out", str(tmp_path / sensors)]) == 0
    capsys.readouterr()
    runs = {s: read_trajectory(tmp_path / s, ["x", "y"]) for s in ("sim", "io")}
    assert len(runs["sim"]["x"]) == len(runs["io"]["x"])
    gap = np.hypot(runs["sim"]["x"] - runs["io"]["x"], runs["sim"]["y"] - runs["io"]["y"])
    assert gap.max() < 0.10
    sim, io = (json.loads((tmp_path / s / "summary.json").read_text()) for s in ("sim", "io"))
    assert io["sensors"] == "io" and io["nmea_fixes"] > 50 and io["nmea_bad"] == 0
    assert io["consequence"] == sim["consequence"] == "stop_in_lane"
    assert io["detected"] and io["detection_time_s"] == pytest.approx(sim["detection_time_s"], abs=0.05)


def _parking_lot(**overrides):
    return load_scenario("parking-lot").with_overrides(**{"localization": "msf", "duration": 6.0, "seed": 1,
                                                          **overrides})


def test_a_gnss_stream_that_stops_is_a_fault_and_the_car_stops_in_lane(tmp_path):
    result = run_hil_scenario(_parking_lot(), tmp_path, sensors="io",
                              prepare=lambda link: link.sensor_io.silence_gnss(2.0))
    summary = result.summary
    first = summary["faults"][0]
    assert summary["consequence"] == "chassis_fault" and first["kind"] == "gnss_stalled"
    assert 3.0 <= first["time"] <= 3.2 and first["detail"].startswith("no GNSS fix for")
    assert summary["stop_time_s"] is not None and abs(summary["final_dev_m"]) < 0.2
    assert (tmp_path / "trajectory.csv").exists() and (tmp_path / "birdseye.png").exists()


def test_a_camera_that_stops_is_a_fault_ld3_never_drives_on_blind(tmp_path):
    result = run_hil_scenario(_parking_lot(detector="classical", defense="ld3"), tmp_path, sensors="io",
                              prepare=lambda link: link.sensor_io.drop_camera(1.5))
    first = result.summary["faults"][0]
    assert result.summary["consequence"] == "chassis_fault" and first["kind"] == "camera_stalled"
    assert 2.0 <= first["time"] <= 2.1 and result.summary["camera_frames"] >= 25


def test_io_sensors_need_the_msf(tmp_path):
    with pytest.raises(ValueError, match="needs --localization msf"):
        run_hil_scenario(_parking_lot(localization="truth"), tmp_path, sensors="io")
