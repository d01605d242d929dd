"""camera.mp4: the camera frames of a run with the detected lane lines drawn over them (OpenCV)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from testbed.perception.detection import CameraFrame, LaneDetection
from vehicles.camera_rig import CameraRig

LINE_COLOURS = {"left": (255, 80, 0), "right": (0, 200, 255)}


def draw_detection(image: np.ndarray, ld: LaneDetection, rig: CameraRig) -> np.ndarray:
    """The RGB image with each valid detected line projected through the rig's ground homography."""
    out = image.copy()
    x0, x1 = ld.x_range
    if x1 <= x0:
        return out
    xs = np.linspace(max(x0, 1.0), x1, 40)
    for side, coeffs in (("left", ld.left), ("right", ld.right)):
        if coeffs is None or not np.all(np.isfinite(coeffs)):
            continue
        ys = np.polynomial.polynomial.polyval(xs, coeffs)
        uv = rig.ground_to_pixel(np.stack([xs, ys], axis=1))
        pts = uv[np.isfinite(uv).all(axis=1)].round().astype(np.int32)
        cv2.polylines(out, [pts], False, LINE_COLOURS[side], 1, cv2.LINE_AA)
    return out


class VideoWriter:
    """Collects overlay frames during a run; writes them as an mp4 at the camera rate."""

    def __init__(self, rig: CameraRig, fps: float = 20.0) -> None:
        self.rig = rig
        self.fps = fps
        self.frames: list[np.ndarray] = []

    def add(self, frame: CameraFrame, ld: LaneDetection) -> None:
        if frame.image is not None:
            self.frames.append(draw_detection(frame.image, ld, self.rig))

    def write(self, path: Path) -> None:
        if not self.frames:
            return
        h, w = self.frames[0].shape[:2]
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), self.fps, (w, h))
        for f in self.frames:
            writer.write(np.ascontiguousarray(f[:, :, ::-1]))
        writer.release()
