"""Camera frames for an offline pass, as fast as they can be read: `video:FILE` (stamped by its frame rate),
`v4l2:DEV` (stamped by the clock on arrival) or `images:GLOB` (sorted by name, stamped `1 / fps` apart). Each
frame is an RGB uint8 array with its time (s) from the first frame."""

from __future__ import annotations

import glob
import time
from collections.abc import Generator, Iterator

import numpy as np

from testbed.errors import UserError

SPECS = "video:FILE, v4l2:DEV or images:GLOB"


def frame_stream(spec: str, fps: float) -> Generator[tuple[float, np.ndarray], None, None]:
    """The frames of `spec`; `fps` stamps images (and a video whose container gives no rate)."""
    try:
        import cv2
    except ImportError:
        raise UserError("a camera needs OpenCV: pip install 'ld3-testbed[camera]'") from None
    kind, _, target = spec.partition(":")
    if kind not in ("video", "v4l2", "images") or not target:
        raise UserError(f"--camera takes {SPECS}, got {spec!r}")
    if fps <= 0:
        raise UserError(f"--fps must be > 0, got {fps:g}")
    if kind == "images":
        yield from _images(cv2, target, fps)
        return
    capture = cv2.VideoCapture(target, cv2.CAP_V4L2 if kind == "v4l2" else cv2.CAP_ANY)
    if not capture.isOpened():
        raise UserError(f"cannot open camera {spec}")
    rate = capture.get(cv2.CAP_PROP_FPS) if kind == "video" else 0.0
    period = 1.0 / (rate if rate > 0 else fps)
    start, k = time.monotonic(), 0
    try:
        while True:
            ok, bgr = capture.read()
            if not ok:
                return
            t = k * period if kind == "video" else time.monotonic() - start
            yield t, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            k += 1
    finally:
        capture.release()


def _images(cv2, pattern: str, fps: float) -> Iterator[tuple[float, np.ndarray]]:
    paths = sorted(glob.glob(pattern, recursive=True))
    if not paths:
        raise UserError(f"no image matches {pattern}")
    for k, path in enumerate(paths):
        bgr = cv2.imread(path, cv2.IMREAD_COLOR)
        if bgr is None:
            raise UserError(f"cannot read image {path}")
        yield k / fps, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
