"""`ld3 vehicle` on a bench whose GNSS comes from where the car truly is (`vehicle_truth.TruthBench`): a chassis
without a yaw-rate report keeps its lane through a curve, a receiver that sends a non-finite or absurd HDOP
ends the drive as a fault with an in-lane stop and every output written, and a drive spoofed sideways, recorded
with `--record`, replays to the same detection time."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from testbed.cli import main
from testbed.rates import CONTROL_HZ
from tests.hil.vehicle.slow_profile import slow_dev_profile
from tests.hil.vehicle.vehicle_truth import TruthBench, lane_video


@pytest.fixture
def slow_profile(tmp_path):
    """ld3-dev (no yaw-rate report) at a slow cycle (`slow_dev_profile`)."""
    return slow_dev_profile(tmp_path)


def _drive(bench: TruthBench, profile: str, out, track: str, *extra: str) -> int:
    return main(["vehicle", "--map", track, "--gnss", f"nmea:{bench.path}", "--interface", "virtual",
                 "--channel", bench.channel, "--profile", profile, "--defense", "none", "--detector", "none",
                 "--out", str(out), *extra])


def test_vehicle_follows_its_gnss_at_the_control_rate_for_its_duration(slow_profile, tmp_path, capsys):
    bench = TruthBench(slow_profile, "parking-lot", 5.0)
    try:
        code = _drive(bench, slow_profile, tmp_path / "run", "parking-lot", "--speed", "1", "--duration", "3")
        last = bench._pose()
    finally:
        bench.close()
    assert code == 0, capsys.readouterr().err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["consequence"] == "reach_destination" and summary["faults"] == []
    assert summary["nmea_fixes"] >= 25 and summary["can_frames_rx"] > 0 and (tmp_path / "run" / "can.asc").exists()
    assert summary["yaw_rate_source"].startswith("bicycle model") and summary["ended_by"] == "duration"
    rows = (tmp_path / "run" / "trajectory.csv").read_text().splitlines()[1:]
    t = [float(row.split(",")[0]) for row in rows]
    span = t[-1] - t[0] + 1.0 / CONTROL_HZ
    assert abs(span - 3.0) <= 1.0 / CONTROL_HZ  # 3 s of chassis time, not a count of rows
    assert (t[-1] - t[0]) / (len(t) - 1) == pytest.approx(1.0 / CONTROL_HZ, rel=0.1)  # ticks at the control rate
    x, y = (float(v) for v in rows[-1].split(",")[1:3])
    assert np.hypot(x - last.x, y - last.y) < 1.0  # the MSF follows the fixes
    assert "vehicle on parking-lot: consequence reach_destination" in capsys.readouterr().out


def test_a_curve_on_a_chassis_without_yaw_rate_keeps_its_lane(slow_profile, tmp_path, capsys):
    bench = TruthBench(slow_profile, "urban-curvy", 150.0)
    try:
        code = _drive(bench, slow_profile, tmp_path / "run", "urban-curvy", "--speed", "4", "--duration", "12")
        off = bench.off_lane_m()
    finally:
        bench.close()
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["yaw_rate_source"].startswith("bicycle model") and summary["consequence_basis"] == "estimated"
    assert code == 0, capsys.readouterr().err
    assert summary["consequence"] == "reach_destination" and summary["max_abs_msf_dev_m"] < 0.3
    assert off < 0.3  # the true car, not only the estimate, kept its lane


@pytest.mark.parametrize("hdop", [float("inf"), 1e-300])
def test_a_receiver_with_an_absurd_hdop_ends_the_drive_as_a_fault_in_lane(slow_profile, tmp_path, capsys, hdop):
    bench = TruthBench(slow_profile, "parking-lot", 5.0, hdop=hdop, hostile_after=3.0)
    try:
        code = _drive(bench, slow_profile, tmp_path / "run", "parking-lot", "--speed", "3", "--duration", "20")
        off = bench.off_lane_m()
    finally:
        bench.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 3 and re.match(r"ld3: chassis fault: (gnss_rejected|gnss_stalled|localization_lost) at", err[-1])
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["consequence"] == "chassis_fault" and summary["ended_by"] == "standstill"
    assert summary["sim_time_s"] < 8.0 and (tmp_path / "run" / "trajectory.csv").exists()
    assert summary["nmea_refused"]["hdop"] >= 1 and summary["nmea_refused"]["position"] == 0
    assert off < 0.3  # the in-lane stop


def test_a_recorded_spoofed_drive_replays_to_the_same_detection_time(slow_profile, tmp_path, capsys):
    video = tmp_path / "lane.avi"
    lane_video(video, 20.0)
    bench = TruthBench(slow_profile, "parking-lot", 5.0, push_mps=0.3, push_after=2.0)
    try:
        code = main(["vehicle", "--map", "parking-lot", "--gnss", f"nmea:{bench.path}", "--interface", "virtual",
                     "--channel", bench.channel, "--profile", slow_profile, "--camera", f"video:{video}",
                     "--detector", "classical", "--speed", "2", "--duration", "12", "--record",
                     "--out", str(tmp_path / "run")])
    finally:
        bench.close()
    assert code == 0, capsys.readouterr().err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["detected"] and summary["detection_time_s"] > 2.0 and summary["alarm_check"] == "lateral-lines"
    capsys.readouterr()
    assert main(["replay", str(tmp_path / "run"), "--out", str(tmp_path / "replay")]) == 0
    assert f"ld3 detects at {summary['detection_time_s']:.2f} s" in capsys.readouterr().out


def test_an_ld3_drive_reports_the_steering_offset_odometry_s_fit_reads(slow_profile, tmp_path, capsys):
    """The bench's kinematic chassis steers exactly as it reports: LD3's fit of the derived yaw rate reads no offset."""
    video = tmp_path / "lane.avi"
    lane_video(video, 20.0)
    bench = TruthBench(slow_profile, "parking-lot", 5.0)
    try:
        code = main(["vehicle", "--map", "parking-lot", "--gnss", f"nmea:{bench.path}", "--interface", "virtual",
                     "--channel", bench.channel, "--profile", slow_profile, "--camera", f"video:{video}",
                     "--detector", "classical", "--speed", "2", "--duration", "12", "--out", str(tmp_path / "run")])
    finally:
        bench.close()
    assert code == 0, capsys.readouterr().err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert abs(summary["odometry_bias_rad_per_m"]) < 1e-4 and not summary["detected"]
    line = next(li for li in capsys.readouterr().out.splitlines() if li.startswith("odometry:"))
    assert re.search(r"a steering-angle offset of [+-]0\.0[0-9]°", line)
