"""Lag of the tracked deviation on a lane change synthesised from a real video: each frame is rectified as if the
camera sat `s(t)` further left (a smooth step of `--shift` m over `--duration` s, starting at `--start` s) and
turned by the heading that lateral speed takes at `--speed` m/s, which moves the road the detector sees as a real
sideways move would (the rectification maps the road plane exactly). The tracked deviation of the shifted run
minus that of the plain run should be −s(t); the lag is the delay τ that best fits it to −s(t − τ), and the
p95 frame-to-frame change is that of the shifted run.
Run: python docs/cameras/shifted_lane_change.py CAL.toml VIDEO [--shift 1.5] [--speed 25]
"""

from __future__ import annotations

import argparse
import dataclasses
import math

import cv2
import numpy as np

from hil.vehicle.camera_calibration import CameraCalibration, Rectifier
from hil.vehicle.camera_detect import CAMERA_ONLY_TRACKER, LaneCentre
from hil.vehicle.frame_stream import frame_stream
from testbed.lane_detection import CameraFrame
from testbed.lane_tracker import LaneTracker
from testbed.perception.detectors.registry import make_detector
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle


def step(t: np.ndarray | float, start: float, duration: float) -> np.ndarray:
    """Smooth 0 -> 1 (cosine) between `start` and `start + duration`."""
    u = np.clip((np.asarray(t) - start) / duration, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(math.pi * u)


def tracked_deviation(cal, video, detector, rig, speed, shift, start, duration, tracking=True) -> tuple:
    tracker, centre, out, times = LaneTracker(CAMERA_ONLY_TRACKER), LaneCentre(), [], []
    for t, rgb in frame_stream(f"video:{video}", 25.0):
        s = shift * float(step(t, start, duration))
        rate = shift * math.pi / (2 * duration) * math.sin(math.pi * float(np.clip((t - start) / duration, 0, 1)))
        heading = math.degrees(math.atan2(rate, speed)) if speed > 0 else 0.0
        moved = dataclasses.replace(cal, mount_y=cal.mount_y + s, yaw_deg=cal.yaw_deg + heading)
        ld = detector.detect(CameraFrame(t, Rectifier(moved, rig)(rgb)))
        if tracking:
            ld = tracker.update(ld, speed, 0.0)
        dev, _ = centre(ld)
        out.append(np.nan if dev is None else dev)
        times.append(t)
    return np.array(times), np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("calibration")
    ap.add_argument("video")
    ap.add_argument("--shift", type=float, default=1.5)
    ap.add_argument("--duration", type=float, default=2.0)
    ap.add_argument("--start", type=float, default=3.0)
    ap.add_argument("--speed", type=float, default=25.0, help="speed of the synthetic heading and the tracker")
    ap.add_argument("--detector", default="neural")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    cal = CameraCalibration.load(args.calibration)
    rig = CameraRig(get_vehicle("sedan").camera)
    det = make_detector(args.detector, track=None, rig=rig)
    for speed in (args.speed, 0.0):
        t, plain = tracked_deviation(cal, args.video, det, rig, speed, 0.0, args.start, args.duration)
        _, moved = tracked_deviation(cal, args.video, det, rig, speed, args.shift, args.start, args.duration)
        _, raw = tracked_deviation(cal, args.video, det, rig, speed, args.shift, args.start, args.duration,
                                   tracking=False)
        d = moved - plain
        lags = np.arange(0.0, 0.6001, 0.01)
        rms = [np.sqrt(np.nanmean((d + args.shift * step(t - lag, args.start, args.duration)) ** 2)) for lag in lags]
        jumps = np.abs(np.diff(moved))
        raw_jumps = np.abs(np.diff(raw))
        print(f"tracker speed {speed:g} m/s: lag {lags[int(np.argmin(rms))]:.2f} s (rms {min(rms):.3f} m), p95 "
              f"frame-to-frame change tracked {np.nanpercentile(jumps, 95):.3f} m, detector "
              f"{np.nanpercentile(raw_jumps, 95):.3f} m")


if __name__ == "__main__":
    main()
