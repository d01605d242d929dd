"""Camera frames for the loop from a source outside it: a V4L2 device or a video file (OpenCV), or frames a
simulator hands over (sensor-level HIL). A thread reads the source; the loop takes the newest frame, stamped
with the reader's clock on arrival. No new frame for `stall_s` (a camera that stops, a file that ends) is a
stall the run reports as a fault: LD3 never runs on without its lane detector.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from typing import Protocol

import numpy as np

from testbed.errors import UserError
from testbed.lane_detection import CameraFrame
from tracks.pose import Pose

DEFAULT_STALL_S = 0.5


class FrameSource(Protocol):
    """Frames as RGB uint8 arrays: `read` blocks until the next one, None once the source has ended."""

    def read(self) -> np.ndarray | None: ...

    def close(self) -> None: ...


class OpenCvSource:
    """`v4l2:/dev/videoN` (a camera) or `video:PATH` (a file, paced at its frame rate) through OpenCV."""

    def __init__(self, spec: str) -> None:
        try:
            import cv2
        except ImportError:
            raise UserError("a camera needs OpenCV: pip install 'ld3-testbed[camera]'") from None
        kind, _, target = spec.partition(":")
        if kind not in ("v4l2", "video") or not target:
            raise UserError(f"camera takes v4l2:/dev/videoN or video:PATH, got {spec!r}")
        self._cv2 = cv2
        backend = cv2.CAP_V4L2 if kind == "v4l2" else cv2.CAP_ANY
        self.capture = cv2.VideoCapture(target, backend)
        if not self.capture.isOpened():
            raise UserError(f"cannot open camera {spec}")
        fps = self.capture.get(cv2.CAP_PROP_FPS) if kind == "video" else 0.0
        self.period = 1.0 / fps if fps > 0 else 0.0
        self._next = time.monotonic()

    def read(self) -> np.ndarray | None:
        ok, bgr = self.capture.read()
        if not ok:
            return None
        if self.period:
            self._next += self.period
            time.sleep(max(0.0, self._next - time.monotonic()))
        return self._cv2.cvtColor(bgr, self._cv2.COLOR_BGR2RGB)

    def close(self) -> None:
        self.capture.release()


class HandedFrames:
    """A FrameSource fed by `put` (a simulator's rendered frames); `end()` makes the reader see its end."""

    def __init__(self) -> None:
        self._frames: queue.Queue[np.ndarray | None] = queue.Queue()

    def put(self, image: np.ndarray) -> None:
        self._frames.put(image)

    def end(self) -> None:
        self._frames.put(None)

    def read(self) -> np.ndarray | None:
        return self._frames.get()

    def close(self) -> None:
        self.end()


class CameraReader:
    """Reads `source` on its own thread, passing each frame through `rectify` (None: as is)."""

    def __init__(self, source: FrameSource, clock: Callable[[], float],
                 rectify: Callable[[np.ndarray], np.ndarray] | None = None, stall_s: float = DEFAULT_STALL_S) -> None:
        self.source = source
        self.clock = clock
        self.rectify = rectify
        self.stall_s = stall_s
        self.frames = 0
        self.ended: str | None = None
        self._latest: tuple[float, np.ndarray] | None = None
        self._taken = -1
        self._arrived = threading.Condition()
        self._started_t = clock()
        self._thread = threading.Thread(target=self._read, name="camera", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        try:
            while (image := self.source.read()) is not None:
                if self.rectify is not None:
                    image = self.rectify(image)
                with self._arrived:
                    self._latest = (self.clock(), image)
                    self.frames += 1
                    self._arrived.notify_all()
            self.ended = "end of stream"
        except (OSError, ValueError) as exc:
            self.ended = " ".join(str(exc).split()) or type(exc).__name__

    def wait_frame(self, count: int, timeout: float) -> bool:
        """Wait until `count` frames have arrived (at most `timeout` s); True if they have."""
        with self._arrived:
            return self._arrived.wait_for(lambda: self.frames >= count, timeout)

    def capture(self, t: float, pose: Pose | None = None) -> CameraFrame:
        """The newest frame not yet taken, at time `t`; a frame with no image where none has arrived since."""
        with self._arrived:
            latest, count = self._latest, self.frames
        if latest is None or count == self._taken:
            return CameraFrame(t, None, pose)
        self._taken = count
        return CameraFrame(t, latest[1], pose)

    def stalled(self, now: float) -> str | None:
        """Why the camera counts as stalled at `now`, else None."""
        with self._arrived:
            last = self._latest[0] if self._latest is not None else self._started_t
        if now - last <= self.stall_s:
            return None
        why = f"no camera frame for {now - last:.2f} s ({self.frames} frames)"
        return f"{why}; stream ended: {self.ended}" if self.ended else why

    def close(self) -> None:
        self.source.close()
        self._thread.join(timeout=1.0)
