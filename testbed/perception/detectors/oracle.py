"""Oracle lane detector: the map's ego lines through the frame's true pose, with optional noise and dropout.

Each line is the map's, fitted over the range ahead where a cubic follows it (`labels`; the detection's x range
is the shorter of the two). Each present line gets its offset c0 perturbed by N(0, noise_std²) and is dropped
(None, probability 0) with probability `dropout`; a line that is not painted in view is always None with
probability 0.
"""

from __future__ import annotations

import numpy as np

from testbed.errors import UserError
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.perception.detectors.labels import LineTruth, ego_lines
from tracks.map_api import OffMapError

MIN_VAR = 1e-4
"""Smallest c0 variance the oracle reports (m²): (1 cm)², its map sampling."""


class OracleLaneDetector(LaneDetector):
    """Ground-truth detector for trace-style runs and as the reference of the other detectors; it reports
    its c0 variance as noise_std² (at least `MIN_VAR`)."""

    reports_variance = True
    reads_camera = False

    def __init__(self, track, rng: np.random.Generator, noise_std: float = 0.0, dropout: float = 0.0) -> None:
        if noise_std < 0.0 or not 0.0 <= dropout <= 1.0:
            raise UserError(f"need noise_std >= 0 and dropout in [0, 1], got {noise_std}, {dropout}")
        self.track = track
        self.rng = rng
        self.noise_std = noise_std
        self.dropout = dropout

    def _observe(self, line: LineTruth) -> tuple[np.ndarray | None, float]:
        if not line.exists:
            return None, 0.0
        if self.dropout > 0.0 and self.rng.random() < self.dropout:
            return None, 0.0
        coeffs = line.coeffs.copy()
        if self.noise_std > 0.0:
            coeffs[0] += self.rng.normal(0.0, self.noise_std)
        return coeffs, 1.0

    def detect(self, frame: CameraFrame) -> LaneDetection:
        if frame.true_pose is None:
            return LaneDetection.empty(frame.t)
        try:
            truth = ego_lines(self.track, frame.true_pose)
        except OffMapError:
            return LaneDetection.empty(frame.t)
        left, left_prob = self._observe(truth.left)
        right, right_prob = self._observe(truth.right)
        var = max(self.noise_std**2, MIN_VAR)
        return LaneDetection(frame.t, left, right, left_prob, right_prob, (0.0, min(truth.left.x_far,
                                                                                  truth.right.x_far)),
                             var if left is not None else None, var if right is not None else None)
