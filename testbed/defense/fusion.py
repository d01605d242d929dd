"""Safety-driven fusion of the MSF and LD lateral deviations (paper Alg. 2 with Alg. 4).

Per lane detection: (R_MSF, R_LD) from the deviation histories, then kf.update(D_MSF, R_MSF), predict,
kf.update(D_LD, R_LD), predict. Without a D_MSF (fail-closed mode, an MSF pose the map cannot place) the
MSF update is left out: predict, kf.update(D_LD, P^LD), predict, with R_MSF = ∞ and its gain 0.
The fused deviation d is placed on the lane centreline point along the lane normal (`pose_on_lane`) to
give the pose the controller uses during attack response.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from testbed.defense.scalar_kalman import ScalarKalman
from testbed.defense.uncertainty import DeviationUncertainty
from tracks.pose import Pose


class FusionStep(NamedTuple):
    """One fusion update: fused deviation, the two uncertainties and the two Kalman gains (Fig. 9)."""

    d: float
    r_msf: float
    r_ld: float
    gain_msf: float
    gain_ld: float


class SafetyDrivenFusion:
    """Alg. 2's 1-D Kalman fusion, its state starting on the centreline (d = 0) with variance p0;
    `power` is the exponent on Alg. 4's history term (1 in the paper)."""

    def __init__(self, window: int, lam: float, q: float, p0: float, power: float = 1.0) -> None:
        self.uncertainty = DeviationUncertainty(window, lam, power)
        self.kf = ScalarKalman(0.0, p0, q)
        self.last: FusionStep | None = None

    def update(self, d_msf: float, d_ld: float, p_msf: float, p_ld: float) -> FusionStep:
        """One Alg. 2 step with the sources' own uncertainties P^MSF, P^LD (m²)."""
        r_msf, r_ld = self.uncertainty.update(d_msf, d_ld, p_msf, p_ld)
        k_msf = self.kf.update(d_msf, r_msf)
        self.kf.predict()
        k_ld = self.kf.update(d_ld, r_ld)
        d = self.kf.predict()
        self.last = FusionStep(d, r_msf, r_ld, k_msf, k_ld)
        return self.last

    def carry(self, d: float) -> None:
        """Move the state to `d`, where odometry carried the last fused deviation (its variance is kept): the
        prediction with the car's own lateral motion that the random walk leaves out."""
        self.kf.x = d

    def update_ld(self, d_ld: float, p_ld: float) -> FusionStep:
        """One step on D_LD alone, measured with LD's own uncertainty P^LD (m²); the histories are unchanged."""
        self.kf.predict()
        k_ld = self.kf.update(d_ld, p_ld)
        d = self.kf.predict()
        self.last = FusionStep(d, math.inf, p_ld, 0.0, k_ld)
        return self.last


def pose_on_lane(point: np.ndarray, heading: float, d: float, yaw: float) -> Pose:
    """The centreline point shifted by d along the lane's left normal, with heading `yaw`."""
    h = float(heading)
    return Pose(float(point[0]) - d * math.sin(h), float(point[1]) + d * math.cos(h), float(yaw))
