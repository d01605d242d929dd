"""camera.mp4: the camera frames of a run with the detected lane lines and the defense's signals drawn over
them, encoded as H.264 (libx264, yuv420p: plays in browsers) by the ffmpeg that imageio-ffmpeg ships."""

from __future__ import annotations

import math
import shutil
import tempfile
from collections.abc import Generator
from dataclasses import dataclass
from pathlib import Path

import cv2
import imageio_ffmpeg
import numpy as np

from testbed.lane_detection import CameraFrame, LaneDetection
from testbed.loop import TickRecord
from vehicles.camera_rig import CameraRig

LINE_COLOURS = {"left": (255, 80, 0), "right": (0, 200, 255)}
TEXT = (255, 255, 255)
AR_COLOUR = (255, 60, 60)
BAR_COLOUR = (120, 200, 255)
CRF = 23
"""x264 constant rate factor (0 lossless … 51 worst; 23 is x264's own default)."""


@dataclass(frozen=True)
class FrameSignals:
    """What the overlay prints on one frame: time (s), D_LD and D_MSF (m), the CUSUM against its
    threshold τ (None where the defense has no statistic), and the defense mode (`normal` or `ar`)."""

    t: float
    ld_dev: float | None
    msf_dev: float | None
    cusum: float | None
    tau: float | None
    mode: str

    @staticmethod
    def of(rec: TickRecord, tau: float | None) -> FrameSignals:
        """The signals of the control tick the frame arrived on; `tau` = the defense's `alarm_threshold`."""
        return FrameSignals(rec.t, rec.ld_dev, rec.msf_dev, rec.cusum, tau, rec.mode)


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


def _metres(value: float | None) -> str:
    return "  -  " if value is None or not math.isfinite(value) else f"{value:+.2f} m"


def draw_signals(image: np.ndarray, s: FrameSignals) -> np.ndarray:
    """The RGB image with a translucent band across its top (the sky): t and mode, D_LD and D_MSF, and the
    CUSUM as a bar whose white tick marks τ (the bar turns red above it)."""
    out = image.copy()
    w = out.shape[1]
    scale = max(0.3, w / 900.0)
    row = max(10, round(28 * scale))
    band = out[: 3 * row + 4]
    band[:] = (band * 0.35).astype(np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    ar = s.mode == "ar"

    def text(msg: str, x: int, line: int, colour: tuple[int, int, int] = TEXT) -> None:
        cv2.putText(out, msg, (x, (line + 1) * row), font, scale, colour, 1, cv2.LINE_AA)

    text(f"t {s.t:6.2f} s", 3, 0)
    text("AR" if ar else "normal", w // 2, 0, AR_COLOUR if ar else TEXT)
    text(f"D_LD {_metres(s.ld_dev)}", 3, 1)
    text(f"D_MSF {_metres(s.msf_dev)}", w // 2, 1)
    if s.cusum is None or not math.isfinite(s.cusum):
        text("CUSUM  -", 3, 2)
        return out
    label = f"CUSUM {s.cusum:.2f}" + (f"/{s.tau:.2f}" if s.tau is not None else "")
    text(label, 3, 2)
    if s.tau is None or s.tau <= 0:
        return out
    x0, x1 = w // 2, w - 4
    y0, y1 = 2 * row + 3, 3 * row + 1
    full = 1.5 * s.tau
    fill = x0 + round((x1 - x0) * min(max(s.cusum, 0.0), full) / full)
    cv2.rectangle(out, (x0, y0), (x1, y1), TEXT, 1)
    cv2.rectangle(out, (x0, y0), (fill, y1), AR_COLOUR if s.cusum > s.tau else BAR_COLOUR, -1)
    tick = x0 + round((x1 - x0) / 1.5)
    cv2.line(out, (tick, y0 - 2), (tick, y1 + 2), TEXT, 1)
    return out


def pad_even(image: np.ndarray) -> np.ndarray:
    """The image padded with black at the bottom and right to even height and width (yuv420p needs both)."""
    h, w = image.shape[:2]
    if h % 2 == 0 and w % 2 == 0:
        return image
    return cv2.copyMakeBorder(image, 0, h % 2, 0, w % 2, cv2.BORDER_CONSTANT, value=(0, 0, 0))


class VideoWriter:
    """Encodes overlay frames as they arrive into a temporary H.264 mp4 at the camera rate; `write(path)`
    finishes the stream and moves the file to `path`. Every frame must have the size of the first."""

    def __init__(self, rig: CameraRig, fps: float = 20.0) -> None:
        self.rig = rig
        self.fps = fps
        self.frames = 0
        self._size: tuple[int, int] | None = None
        self._encoder: Generator[None, bytes, None] | None = None
        self._tmp_dir: tempfile.TemporaryDirectory[str] | None = None

    def add(self, frame: CameraFrame, ld: LaneDetection, signals: FrameSignals) -> None:
        if frame.image is None:
            return
        image = pad_even(draw_signals(draw_detection(frame.image, ld, self.rig), signals))
        h, w = image.shape[:2]
        if self._encoder is None:
            self._open((w, h))
        elif (w, h) != self._size:
            raise ValueError(f"camera frame size changed from {self._size} to {(w, h)}")
        self._encoder.send(np.ascontiguousarray(image, dtype=np.uint8).tobytes())
        self.frames += 1

    def _open(self, size: tuple[int, int]) -> None:
        self._size = size
        self._tmp_dir = tempfile.TemporaryDirectory(prefix="ld3-video-")
        self._encoder = imageio_ffmpeg.write_frames(
            str(Path(self._tmp_dir.name) / "camera.mp4"), size, fps=self.fps, codec="libx264",
            pix_fmt_in="rgb24", pix_fmt_out="yuv420p", quality=None, macro_block_size=2,
            output_params=["-crf", str(CRF), "-preset", "medium", "-movflags", "+faststart"])
        self._encoder.send(None)

    def write(self, path: Path) -> None:
        """Finish the video and move it to `path`; nothing is written when no frame arrived."""
        if self._encoder is None or self._tmp_dir is None:
            return
        self._encoder.close()
        self._encoder = None
        shutil.move(Path(self._tmp_dir.name) / "camera.mp4", path)
        self.close()

    def close(self) -> None:
        """Abandon an unfinished video (stops the encoder, removes the temporary file)."""
        if self._encoder is not None:
            self._encoder.close()
            self._encoder = None
        if self._tmp_dir is not None:
            self._tmp_dir.cleanup()
            self._tmp_dir = None
