"""A real 2-s LD3 run recorded into camera.mp4 and run.mcap, fed the way the runner feeds them: each camera
frame with its lane detection, paired with the record of the control tick it arrived on."""

import json
from collections import Counter

import imageio_ffmpeg
import numpy as np
from mcap.reader import make_reader

from testbed.eval.recording import Recording, ego_lane_lines, fused_pose
from testbed.eval.runner import SimRun
from testbed.eval.scenario import load_scenario
from testbed.eval.video import FrameSignals, VideoWriter


def test_a_simulated_run_records_every_camera_frame_and_tick(tmp_path):
    sc = load_scenario("urban-straight").with_overrides(duration=2.0, defense="ld3")
    sim = SimRun(sc, render=True)
    pending = []
    sim.loop.on_frame = lambda frame, ld: pending.append((frame, ld))
    video = VideoWriter(sim.rig, fps=sim.loop.rates.camera_hz)
    recording = Recording(sim.rig)
    tau = sim.defense.alarm_threshold
    path = []
    try:
        for _ in range(round(sc.duration * sim.loop.rates.control_hz)):
            rec = sim.loop.tick()
            msf = sim.loop.last_estimate.pose
            for frame, ld in pending:
                video.add(frame, ld, FrameSignals.of(rec, tau))
                recording.add_camera(frame.t, frame.image, ld)
            pending.clear()
            recording.add_tick(rec, msf, fused_pose(rec, msf, sim.smap, sim.lane), tau)
            path.append((rec.x, rec.y))
        recording.set_lane_lines(ego_lane_lines(sim.track.lanes[sim.lane], np.array(path)))
        video.write(tmp_path / "camera.mp4")
        recording.write(tmp_path / "run.mcap")
    finally:
        sim.close()

    frames = imageio_ffmpeg.read_frames(str(tmp_path / "camera.mp4"))
    meta = next(frames)
    assert meta["codec"] == "h264" and meta["size"] == (sim.rig.width, sim.rig.height)
    assert sum(1 for _ in frames) == 40
    with open(tmp_path / "run.mcap", "rb") as f:
        messages = [(c.topic, json.loads(m.data)) for _, c, m in make_reader(f).iter_messages()]
    counts = Counter(topic for topic, _ in messages)
    assert counts == {"/camera/image": 40, "/pose/true": 200, "/pose/msf": 200, "/signals": 200, "/map/lanes": 1}
    signals = [m for topic, m in messages if topic == "/signals"]
    assert all(m["tau"] == tau and m["mode"] == "normal" for m in signals)
    assert signals[-1]["cusum"] is not None and signals[-1]["ld_dev"] is not None
