"""`ld3 vehicle` without a simulator: an ECU process on an SLCAN pty stands in for the chassis, a thread writes
NMEA along the map's lane onto a pty, a video file is the camera. The run follows the fixes, writes its outputs
and ends on a stalled GNSS stream or camera as a fault (exit 3)."""

from __future__ import annotations

import json
import os
import threading
import time
import tty

import cv2
import numpy as np
import pytest

from hil.link.ecu_process import EcuProcess
from hil.link.timing import ClockMode
from hil.vehicle.geodetic import DEFAULT_ORIGIN, LocalTangentPlane
from hil.vehicle.nmea_out import gga_sentence
from testbed.cli import main
from testbed.localization.sensors import GnssFix
from testbed.presets import build_track
from tests.hil.vehicle.slow_profile import slow_dev_profile

PLANE = LocalTangentPlane(*DEFAULT_ORIGIN)


class NmeaFeeder:
    """Writes GGA at 10 Hz for a car moving at `speed` along lane 0 of parking-lot from s = 5 m, for `seconds`."""

    def __init__(self, speed: float = 1.0, seconds: float = 30.0) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.track = build_track("parking-lot")
        self.speed, self.seconds = speed, seconds
        self.last_xy: tuple[float, float] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._feed, daemon=True)
        self._thread.start()

    def _feed(self) -> None:
        t0 = time.monotonic()
        while not self._stop.is_set() and (t := time.monotonic() - t0) < self.seconds:
            pose = self.track.start_pose(0, 5.0 + self.speed * t)
            self.last_xy = (pose.x, pose.y)
            os.write(self.master, gga_sentence(GnssFix(t, np.array(self.last_xy), np.eye(2) * 0.04), PLANE, 4))
            self._stop.wait(0.1)

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        os.close(self.master)
        os.close(self.slave)


@pytest.fixture
def ecu(tmp_path):
    """A realtime ECU process on a pty, speaking ld3-dev at a 50 ms cycle with 500 ms time-outs, so that a
    starved process on the shared test machine does not trip the time-outs, which these tests are not about."""
    profile = slow_dev_profile(tmp_path)
    process = EcuProcess(plant="kinematic", clock=ClockMode.REALTIME, profile=profile)
    yield process, profile
    process.stop()


def _vehicle(ecu, feeder, out, *extra: str) -> int:
    process, profile = ecu
    return main(["vehicle", "--map", "parking-lot", "--gnss", f"nmea:{feeder.path}", "--interface", "slcan",
                 "--channel", process.tty_path, "--profile", profile, "--speed", "1", "--out", str(out), *extra])


def test_a_gnss_stream_that_stops_ends_the_vehicle_run_as_a_fault(ecu, tmp_path, capsys):
    feeder = NmeaFeeder(seconds=1.5)
    try:
        code = _vehicle(ecu, feeder, tmp_path / "run", "--defense", "none", "--detector", "none", "--duration", "10")
    finally:
        feeder.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 3 and err[-1].startswith("ld3: chassis fault: gnss_stalled at"), err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["consequence"] == "chassis_fault" and summary["sim_time_s"] < 5.0


def test_ld3_on_a_camera_that_ends_stops_as_a_fault(ecu, tmp_path, capsys):
    video = tmp_path / "camera.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 20.0, (320, 160))
    for _ in range(30):
        writer.write(np.full((160, 320, 3), 90, np.uint8))
    writer.release()
    feeder = NmeaFeeder(speed=0.0)  # fixes where the car stands: a feed that disagrees with it is a fault of its own
    try:
        code = _vehicle(ecu, feeder, tmp_path / "run", "--camera", f"video:{video}", "--detector", "classical",
                        "--duration", "10", "--speed", "0.2")
    finally:
        feeder.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 3 and err[-1].startswith("ld3: chassis fault: camera_stalled at"), err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["defense"] == "ld3" and 20 <= summary["camera_frames"] <= 30


def test_a_camera_whose_frames_do_not_fit_the_detector_is_refused_before_the_drive(ecu, tmp_path, capsys):
    video = tmp_path / "camera.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 20.0, (960, 540))
    for _ in range(3):
        writer.write(np.full((540, 960, 3), 90, np.uint8))
    writer.release()
    feeder = NmeaFeeder(speed=0.0)
    try:
        code = _vehicle(ecu, feeder, tmp_path / "run", "--camera", f"video:{video}", "--detector", "classical")
    finally:
        feeder.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "camera frames are 960x540 but the detector reads the 320x160 view" in err[0], err
    assert "give --calibration" in err[0] and not (tmp_path / "run" / "summary.json").exists()


def test_vehicle_refuses_what_cannot_run_on_a_vehicle(tmp_path, capsys):
    for extra, message in ((["--detector", "oracle"], "needs the simulator's true pose"),
                           (["--detector", "neural"], "reads a camera: give --camera"),
                           (["--detector", "none"], "defense ld3 needs a lane detector")):
        assert main(["vehicle", "--map", "parking-lot", "--gnss", "nmea:/dev/null", *extra]) == 2
        assert message in capsys.readouterr().err


def test_vehicle_refuses_bad_arguments_in_one_line(tmp_path, capsys):
    for extra, message in ((["--origin", "91,0"], "--origin takes LAT,LON"),
                           (["--origin", "nan,nan"], "--origin takes LAT,LON"),
                           (["--origin", "48.1"], "--origin takes LAT,LON"),
                           (["--lane", "99", "--defense", "none", "--detector", "none"], "--lane 99: parking-lot"),
                           (["--scenario", str(tmp_path / "none.toml")], "cannot read scenario")):
        assert main(["vehicle", "--map", "parking-lot", "--gnss", "nmea:/dev/null", *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
