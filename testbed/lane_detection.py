"""The lane-detection contract (docs/architecture.md, "Conventions"), shared by perception, the loop and the
defenses: ego left and right lines as cubics y(x) in the vehicle frame.

Coefficients are in ascending powers, y = c0 + c1 x + c2 x² + c3 x³, so `|c0|` is the distance from
the vehicle reference point to that line (paper Fig. 13, Alg. 3). The left line has y > 0.
`left_var` / `right_var` are the variances of c0 (m²) where the detector reports its own uncertainty.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from tracks.pose import Pose


@dataclass(frozen=True)
class LaneDetection:
    timestamp: float
    left: np.ndarray | None
    right: np.ndarray | None
    left_prob: float
    right_prob: float
    x_range: tuple[float, float]
    left_var: float | None = None
    right_var: float | None = None

    @staticmethod
    def empty(timestamp: float) -> LaneDetection:
        return LaneDetection(timestamp, None, None, 0.0, 0.0, (0.0, 0.0))


@dataclass(frozen=True)
class CameraFrame:
    """One rendered (or captured) RGB image, H×W×3 uint8; simulation also carries the true vehicle pose."""

    t: float
    image: np.ndarray
    true_pose: Pose | None = None


class LaneDetector(ABC):
    """Reads a camera frame, returns the ego lane lines. Bad frames give an empty detection, never a crash."""

    reports_variance: bool = False
    """True when every detection carries `left_var` / `right_var` for its present lines."""
    reads_camera: bool = True
    """True when it reads `CameraFrame.image` (the run then renders the camera); False for map-based ones."""

    @abstractmethod
    def detect(self, frame: CameraFrame) -> LaneDetection: ...
