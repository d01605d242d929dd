"""Real runs recorded into camera.mp4 and run.mcap by the runner (`ld3 run --video --record`): every camera
frame and control tick, the fused pose in attack response, and the trajectory unchanged by recording."""

import json
from collections import Counter

import imageio_ffmpeg
from mcap.reader import make_reader

from testbed.defense.config import DefenseConfig
from testbed.eval.run.runner import run_scenario
from testbed.eval.run.scenario import load_scenario
from testbed.rates import CONTROL_HZ


def test_a_simulated_run_records_every_camera_frame_and_tick(tmp_path):
    sc = load_scenario("urban-straight").with_overrides(duration=2.0, defense="ld3")
    result = run_scenario(sc, tmp_path, video=True, record=True)
    frames = imageio_ffmpeg.read_frames(str(tmp_path / "camera.mp4"))
    meta = next(frames)
    assert meta["codec"] == "h264" and meta["size"] == (320, 160)
    assert sum(1 for _ in frames) == 40
    with open(tmp_path / "run.mcap", "rb") as f:
        messages = [(c.topic, json.loads(m.data)) for _, c, m in make_reader(f).iter_messages()]
    counts = Counter(topic for topic, _ in messages)
    ticks = round(2.0 * CONTROL_HZ)
    assert counts == {"/camera/image": 40, "/ld3/input": 40, "/pose/true": ticks, "/pose/msf": ticks,
                      "/signals": ticks, "/map/lanes": 1}
    signals = [m for topic, m in messages if topic == "/signals"]
    assert all(m["tau"] == DefenseConfig().tau and m["mode"] == "normal" for m in signals)
    assert signals[-1]["cusum"] is not None and signals[-1]["ld_dev"] is not None
    assert len(result.rows) == ticks


def test_attack_response_records_the_pose_control_used_and_recording_changes_nothing(tmp_path):
    sc = load_scenario("urban-straight").with_overrides(duration=12.0, defense="ld3", localization="msf",
                                                        attack={"kind": "trace", "trace": "default", "start": 2.0})
    recorded = run_scenario(sc, tmp_path / "rec", record=True)
    plain = run_scenario(sc, tmp_path / "plain")
    assert (tmp_path / "rec" / "trajectory.csv").read_bytes() == (tmp_path / "plain" / "trajectory.csv").read_bytes()
    assert recorded.summary["detected"] and plain.summary["detected"]
    ar_ticks = sum(r.mode == "ar" for r in recorded.rows)
    with open(tmp_path / "rec" / "run.mcap", "rb") as f:
        topics = Counter(c.topic for _, c, _ in make_reader(f).iter_messages())
    assert topics["/pose/fused"] == ar_ticks > 0
    sim_time = recorded.summary["sim_time_s"]
    assert topics["/camera/image"] >= 19 * sim_time  # the camera at 20 Hz: at least 19 frames per simulated second
