"""run.mcap: one run for Foxglove. JSON messages with Foxglove's well-known schemas for the camera (JPEG with
the detected lines), the true, MSF and fused poses, the traffic cars' poses and the ego lane's lines, and the
testbed's own schemas for the per-tick signals, the attack's state and decoded CAN frames. Log and publish
time = simulated time.

World poses and lines are in frame `map` (x east, y north, z up); the image is in frame `camera`.
"""

from __future__ import annotations

import base64
import json
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from testbed.errors import UserError
from testbed.eval.run import mcap_schemas
from testbed.eval.run.ld3_input import ld3_input_message
from testbed.eval.run.video import draw_detection
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.loop import TickRecord
from tracks.lane import Lane
from tracks.pose import Pose
from vehicles.camera_rig import CameraRig

MAP_FRAME = "map"
CAMERA_FRAME = "camera"
LANE_LINES_EVERY_S = 10.0
"""The lane lines are republished this often, so that a viewer seeking anywhere finds them recent."""


@dataclass(frozen=True)
class Channel:
    topic: str
    schema: mcap_schemas.Schema


CAMERA = Channel("/camera/image", mcap_schemas.COMPRESSED_IMAGE)
POSE_TRUE = Channel("/pose/true", mcap_schemas.POSE_IN_FRAME)
POSE_MSF = Channel("/pose/msf", mcap_schemas.POSE_IN_FRAME)
POSE_FUSED = Channel("/pose/fused", mcap_schemas.POSE_IN_FRAME)
LANES = Channel("/map/lanes", mcap_schemas.SCENE_UPDATE)
SIGNALS = Channel("/signals", mcap_schemas.SIGNALS)
ATTACK = Channel("/attack", mcap_schemas.ATTACK)
CAN = Channel("/can", mcap_schemas.CAN_FRAME)
LD3_INPUT = Channel("/ld3/input", mcap_schemas.LD3_INPUT)
TRAFFIC = Channel("/traffic/poses", mcap_schemas.POSES_IN_FRAME)
CHANNELS = (CAMERA, POSE_TRUE, POSE_MSF, POSE_FUSED, LANES, SIGNALS, ATTACK, CAN)


def nanoseconds(t: float) -> int:
    return round(t * 1e9)


def _stamp(t: float) -> dict[str, int]:
    sec, nsec = divmod(max(nanoseconds(t), 0), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def _finite(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def _pose(x: float, y: float, yaw: float) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2.0), "w": math.cos(yaw / 2.0)}}


def _encoded(channel: Channel, t: float, message: Mapping[str, Any]) -> tuple[int, Channel, bytes]:
    return nanoseconds(t), channel, json.dumps(message, separators=(",", ":"), allow_nan=False).encode()


def ego_lane_lines(lane: Lane, path_xy: np.ndarray, margin: float = 30.0, step: float = 1.0) -> list[np.ndarray]:
    """The lane's right and left edges (N × 2 world points) along the stretch a path covers, `margin` m beyond
    each end, sampled every `step` m of the road's arc length (the path is read every 25th point)."""
    xy = np.asarray(path_xy, dtype=float).reshape(-1, 2)
    s = [lane.local_coordinates(float(x), float(y))[0] for x, y in np.vstack([xy[::25], xy[-1:]])]
    s0, s1 = max(min(s) - margin, 0.0), min(max(s) + margin, lane.length)
    stations = np.linspace(s0, s1, max(2, math.ceil((s1 - s0) / step) + 1))
    return [np.array([lane.position(float(si), side * lane.width_at(float(si)) / 2.0) for si in stations])
            for side in (-1.0, 1.0)]


class Recording:
    """Collects a run's messages as they happen; `write(path)` writes them to an MCAP file in time order.
    A channel is in the file when it has at least one message."""

    def __init__(self, rig: CameraRig, jpeg_quality: int = 85) -> None:
        """Refuses to start (one line naming the extra) where the mcap package is not installed."""
        try:
            from mcap.writer import Writer
        except ImportError:
            raise UserError("run.mcap needs the mcap package: pip install 'ld3-testbed[record]'") from None
        self._writer = Writer
        self.rig = rig
        self.jpeg_quality = jpeg_quality
        self._messages: list[tuple[int, Channel, bytes]] = []
        self._lane_lines: list[np.ndarray] = []

    def _add(self, channel: Channel, t: float, message: Mapping[str, Any]) -> None:
        self._messages.append(_encoded(channel, t, message))

    def add_camera(self, t: float, image: np.ndarray, ld: LaneDetection) -> None:
        """One camera frame (RGB, H × W × 3 uint8) and its lane detection: a JPEG with the lines drawn."""
        drawn = draw_detection(image, ld, self.rig)
        ok, jpeg = cv2.imencode(".jpg", np.ascontiguousarray(drawn[:, :, ::-1]),
                                [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if not ok:
            raise ValueError(f"cannot JPEG-encode a camera image of shape {image.shape}")
        self._add(CAMERA, t, {"timestamp": _stamp(t), "frame_id": CAMERA_FRAME,
                              "data": base64.b64encode(jpeg.tobytes()).decode(), "format": "jpeg"})

    def add_ld3_input(self, ld: LaneDetection, est: LocalizationEstimate) -> None:
        """What the defense read at one camera frame (`testbed.eval.run.ld3_input`), for `ld3 replay`."""
        self._add(LD3_INPUT, ld.timestamp, ld3_input_message(ld, est))

    def add_tick(self, rec: TickRecord, msf_pose: Pose | None, fused: Pose | None, tau: float | None) -> None:
        """One control tick: its record (true pose, signals, attack state), the MSF pose, the fused pose control
        used in attack response (None outside it) and the defense's alarm threshold τ (None: no statistic)."""
        t = rec.t
        for channel, pose in ((POSE_TRUE, Pose(rec.x, rec.y, rec.yaw)), (POSE_MSF, msf_pose), (POSE_FUSED, fused)):
            if pose is not None and pose.is_finite():
                self._add(channel, t, {"timestamp": _stamp(t), "frame_id": MAP_FRAME,
                                       "pose": _pose(pose.x, pose.y, pose.yaw)})
        self._add(SIGNALS, t, {
            "t": t, "phys_dev": _finite(rec.phys_dev), "msf_dev": _finite(rec.msf_dev),
            "ld_dev": _finite(rec.ld_dev), "fused_dev": _finite(rec.fused_dev), "cusum": _finite(rec.cusum),
            "tau": _finite(tau), "mode": rec.mode, "ar": int(rec.mode == "ar"), "speed": rec.speed,
            "steer": rec.steer, "accel": rec.accel})
        if rec.attack_stage is not None:
            self._add(ATTACK, t, {"t": t, "stage": rec.attack_stage, "offset": _finite(rec.attack_offset)})

    def add_traffic(self, t: float, poses: Sequence[Pose]) -> None:
        """The traffic cars' poses at time t, in car id order."""
        self._add(TRAFFIC, t, {"timestamp": _stamp(t), "frame_id": MAP_FRAME,
                               "poses": [_pose(p.x, p.y, p.yaw) for p in poses]})

    def add_can(self, t: float, arbitration_id: int, data: bytes, decoded: Mapping[str, Any]) -> None:
        """One CAN frame and its DBC-decoded signals (numbers; named enum values are written as strings)."""
        signals = {name: _finite(float(v)) if isinstance(v, numbers.Real) else str(v) for name, v in decoded.items()}
        self._add(CAN, t, {"t": t, "id": int(arbitration_id), "data": bytes(data).hex(), "signals": signals})

    def set_lane_lines(self, lines: Sequence[np.ndarray]) -> None:
        """World polylines (N × 2) of the map to show, e.g. `ego_lane_lines`; published on `/map/lanes` at
        the first message and every LANE_LINES_EVERY_S after it."""
        self._lane_lines = [np.asarray(line, dtype=float).reshape(-1, 2) for line in lines]

    def _lane_messages(self) -> list[tuple[int, Channel, bytes]]:
        if not self._lane_lines or not self._messages:
            return []
        t0 = min(m[0] for m in self._messages) / 1e9
        t1 = max(m[0] for m in self._messages) / 1e9
        white = {"r": 1.0, "g": 1.0, "b": 1.0, "a": 1.0}
        out = []
        for t in np.arange(t0, t1 + 1e-9, LANE_LINES_EVERY_S):
            lines = [{"type": 0, "pose": _pose(0.0, 0.0, 0.0), "thickness": 0.15, "scale_invariant": False,
                      "points": [{"x": x, "y": y, "z": 0.0} for x, y in line], "color": white}
                     for line in self._lane_lines]
            entity = {"timestamp": _stamp(t), "frame_id": MAP_FRAME, "id": "ego-lane",
                      "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False, "lines": lines}
            out.append(_encoded(LANES, float(t), {"deletions": [], "entities": [entity]}))
        return out

    def write(self, path: Path) -> None:
        """Write every collected message, in log-time order (ties keep the order they arrived in)."""
        messages = sorted(self._messages + self._lane_messages(), key=lambda m: m[0])
        with open(path, "wb") as stream:
            writer = self._writer(stream)
            writer.start(profile="", library="ld3-testbed")
            ids: dict[str, int] = {}
            sequence: dict[str, int] = {}
            for log_time, channel, payload in messages:
                if channel.topic not in ids:
                    schema_id = writer.register_schema(channel.schema["title"], "jsonschema",
                                                       json.dumps(channel.schema).encode())
                    ids[channel.topic] = writer.register_channel(channel.topic, "json", schema_id)
                    sequence[channel.topic] = 0
                writer.add_message(ids[channel.topic], log_time=log_time, data=payload, publish_time=log_time,
                                   sequence=sequence[channel.topic])
                sequence[channel.topic] += 1
            writer.finish()
