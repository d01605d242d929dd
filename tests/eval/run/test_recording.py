"""run.mcap: a synthetic 3-s run (300 control ticks, 60 camera frames, an attack, attack response from 2 s,
CAN frames) written by `Recording` and read back with the mcap reader."""

import base64
import json
import math
from collections import Counter, defaultdict

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader

from testbed.eval.run.recording import CHANNELS, Recording, ego_lane_lines
from testbed.lane_detection import LaneDetection
from testbed.loop import TickRecord
from tracks.pose import Pose
from tracks.presets import load_track
from tracks.semantic_map import TrackMap
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

TICKS, CAMERA_EVERY, AR_FROM = 300, 5, 2.0
TAU = 1.2
FUSED_D = 0.25


def synthetic_run(tmp_path):
    """Drive 10 m/s down the ego lane of urban-straight; the MSF drifts left; AR from 2 s; CAN every 10 ticks."""
    track = load_track("urban-straight")
    lane = track.lanes[track.ego_lane]
    s0 = 20.0
    recording = Recording(CameraRig(get_vehicle("sedan").camera))
    image = np.full((160, 320, 3), 90, np.uint8)
    ld = LaneDetection(0.0, np.array([1.8, 0.0, 0.0, 0.0]), np.array([-1.8, 0.0, 0.0, 0.0]), 1.0, 1.0, (2.0, 40.0))
    path = []
    for i in range(TICKS):
        t = i / 100.0
        x, y = lane.position(s0 + 10.0 * t)
        yaw = lane.heading_at(s0 + 10.0 * t)
        offset = 0.3 * t
        msf = Pose(*lane.position(s0 + 10.0 * t, offset), yaw)
        ar = t >= AR_FROM
        rec = TickRecord(t=t, x=x, y=y, yaw=yaw, speed=10.0, phys_dev=0.0, msf_dev=offset,
                         ld_dev=0.02 if i >= CAMERA_EVERY else None, cusum=0.6 * t, mode="ar" if ar else "normal",
                         steer=0.0, accel=-4.0 if ar else 0.0, ld_fresh=int(i % CAMERA_EVERY == 0),
                         attack_stage="aggressive", attack_offset=offset,
                         fused_dev=FUSED_D if ar else None, heading_used=0.0 if ar else None)
        if i % CAMERA_EVERY == 0:
            recording.add_camera(t, image, ld)
        fused = Pose(*lane.position(s0 + 10.0 * t, FUSED_D), yaw) if ar else None
        recording.add_tick(rec, msf, fused, TAU)
        if i % 10 == 0:
            recording.add_can(t, 0x101, bytes([i % 256, 0, 0, 0]), {"SteerAngle": 1.5, "Mode": _Named("AUTO")})
        path.append((x, y))
    recording.set_lane_lines(ego_lane_lines(lane, np.array(path)))
    out = tmp_path / "run.mcap"
    recording.write(out)
    recording.write(tmp_path / "again.mcap")
    assert out.read_bytes() == (tmp_path / "again.mcap").read_bytes()  # deterministic; writing changes nothing
    return out, track


class _Named:
    """Stands in for a DBC enum value (cantools' NamedSignalValue): not a number, written by its name."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __str__(self) -> str:
        return self.name


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path, track = synthetic_run(tmp_path_factory.mktemp("rec"))
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        messages = [(channel.topic, schema.name, message.log_time, json.loads(message.data))
                    for schema, channel, message in reader.iter_messages(log_time_order=False)]
    return summary, messages, track


def test_every_channel_is_present_with_its_schema_and_message_count(recorded):
    summary, messages, _ = recorded
    schemas = {ch.topic: summary.schemas[ch.schema_id] for ch in summary.channels.values()}
    assert {topic: s.name for topic, s in schemas.items()} == {c.topic: c.schema["title"] for c in CHANNELS}
    assert all(s.encoding == "jsonschema" and json.loads(s.data)["title"] == s.name for s in schemas.values())
    assert all(summary.channels[cid].message_encoding == "json" for cid in summary.channels)
    counts = Counter(topic for topic, *_ in messages)
    seconds = TICKS / 100.0
    assert counts["/camera/image"] / seconds >= 19
    assert counts == {"/camera/image": TICKS // CAMERA_EVERY, "/pose/true": TICKS, "/pose/msf": TICKS,
                      "/pose/fused": TICKS - round(AR_FROM * 100), "/signals": TICKS, "/attack": TICKS,
                      "/can": TICKS // 10, "/map/lanes": 1}


def test_timestamps_are_simulated_time_in_ns_and_monotonic(recorded):
    _, messages, _ = recorded
    times = [log_time for _, _, log_time, _ in messages]
    assert times == sorted(times)  # written in log-time order
    per_topic = defaultdict(list)
    for topic, _, log_time, msg in messages:
        per_topic[topic].append(log_time)
        if "timestamp" in msg:
            assert msg["timestamp"]["sec"] * 1_000_000_000 + msg["timestamp"]["nsec"] == log_time
        if "t" in msg:
            assert log_time == round(msg["t"] * 1e9)
    assert all(np.all(np.diff(ts) > 0) for topic, ts in per_topic.items())
    assert per_topic["/signals"][0] == 0 and per_topic["/signals"][-1] == 2_990_000_000


def test_message_contents_decode(recorded):
    _, messages, track = recorded
    by_topic = defaultdict(list)
    for topic, _, _, msg in messages:
        by_topic[topic].append(msg)
    image = cv2.imdecode(np.frombuffer(base64.b64decode(by_topic["/camera/image"][0]["data"]), np.uint8),
                         cv2.IMREAD_COLOR)
    assert image.shape == (160, 320, 3) and by_topic["/camera/image"][0]["format"] == "jpeg"
    assert (np.abs(image.astype(int) - 90).max(axis=2) > 60).sum() > 50  # the detected lines are drawn
    first, last = by_topic["/signals"][0], by_topic["/signals"][-1]
    assert first["mode"] == "normal" and first["ar"] == 0 and first["ld_dev"] is None and first["fused_dev"] is None
    assert last["mode"] == "ar" and last["ar"] == 1 and last["tau"] == TAU and last["fused_dev"] == FUSED_D
    assert last["cusum"] == pytest.approx(0.6 * 2.99)
    assert by_topic["/attack"][-1] == {"t": 2.99, "stage": "aggressive", "offset": pytest.approx(0.3 * 2.99)}
    assert by_topic["/can"][1] == {"t": 0.1, "id": 0x101, "data": "0a000000",
                                   "signals": {"SteerAngle": 1.5, "Mode": "AUTO"}}
    smap = TrackMap(track)

    def dev(msg) -> float:
        p, q = msg["pose"]["position"], msg["pose"]["orientation"]
        return smap.lane_dev(Pose(p["x"], p["y"], 2.0 * math.atan2(q["z"], q["w"])), track.ego_lane)

    assert dev(by_topic["/pose/true"][-1]) == pytest.approx(0.0, abs=1e-6)
    assert dev(by_topic["/pose/msf"][-1]) == pytest.approx(0.3 * 2.99, abs=1e-6)
    assert all(dev(m) == pytest.approx(FUSED_D, abs=1e-6) for m in by_topic["/pose/fused"])
    lines = by_topic["/map/lanes"][0]["entities"][0]["lines"]
    half = track.lanes[track.ego_lane].width / 2.0
    for line, side in zip(lines, (-1.0, 1.0), strict=True):
        devs = [smap.lane_dev(Pose(p["x"], p["y"], 0.0), track.ego_lane) for p in line["points"][::20]]
        assert devs == pytest.approx([side * half] * len(devs), abs=1e-6)
        assert len(line["points"]) > 60  # 30 m of path plus 30 m beyond each end, every metre
