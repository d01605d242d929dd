"""What localization hands the rest of the stack: a pose with its covariance."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracks.pose import Pose


@dataclass(frozen=True)
class LocalizationEstimate:
    """Fused pose at time t; `cov` is the 3×3 covariance over (x, y, yaw) in the world frame."""

    t: float
    pose: Pose
    cov: np.ndarray

    def lateral_variance(self, heading: float) -> float:
        """Variance of the position across a direction of travel `heading` (rad)."""
        n = np.array([-np.sin(heading), np.cos(heading)])
        return float(n @ self.cov[:2, :2] @ n)
