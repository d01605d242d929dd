"""Localization on a vehicle: the MSF propagated by what the chassis reports (longitudinal acceleration and yaw
rate, its IMU) and updated by GNSS fixes from the NMEA reader; no LiDAR locator.

What it cannot trust is a fault reported through `on_fault`, never driven on: a stalled GNSS stream
(`gnss_stalled`), at least `MAX_REJECTED_FIXES` fixes in a row refused over `MAX_REJECTED_S` (a position or
covariance that is not finite, a standard deviation outside `FIX_STD_RANGE_M`, or the MSF's innovation gate:
`gnss_rejected`), and an MSF pose
that is not finite (`localization_lost`; the last finite estimate is held for the in-lane stop)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from hil.vehicle.nmea_gnss import NmeaGnssReader
from testbed.chassis import ChassisState
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.msf import MsfParams, MultiSensorFusion
from testbed.localization.sensors import GnssFix, ImuSample
from testbed.localization.stack import GnssSpoofer
from tracks.pose import Pose

MAX_REJECTED_FIXES = 10
"""Fixes refused in a row that, over `MAX_REJECTED_S` without an accepted one, make a localization fault."""

MAX_REJECTED_S = 1.0
"""How long (s) the localization may go on refusing its fixes before that is a fault (a backlog of fixes that
queued while the link engaged comes in one tick and is not yet one)."""

FIX_STD_RANGE_M = (1e-3, 1e3)
"""A fix's horizontal standard deviations (m) outside this range are refused: no receiver knows its position to
a millimetre, and one that does not know it within a kilometre carries nothing."""


def usable_fix(fix: GnssFix) -> bool:
    """Finite position, and a finite symmetric covariance with standard deviations within `FIX_STD_RANGE_M`."""
    xy, cov = np.asarray(fix.xy, float), np.asarray(fix.cov, float)
    if xy.shape != (2,) or cov.shape != (2, 2) or not (np.isfinite(xy).all() and np.isfinite(cov).all()):
        return False
    if not np.allclose(cov, cov.T):
        return False
    lo, hi = FIX_STD_RANGE_M
    eig = np.linalg.eigvalsh(cov)
    return bool(eig[0] >= lo * lo and eig[-1] <= hi * hi)


class MeasuredLocalization:
    """The loop's `Localization` from real sensors: `step` fuses the chassis's motion and the fixes that arrived
    since the last tick (stamped at this tick); `start` is the first pose (from the first fix and the map)."""

    def __init__(self, gnss: NmeaGnssReader, start: Pose, on_fault: Callable[[str, str], None],
                 params: MsfParams | None = None) -> None:
        self.gnss = gnss
        self.on_fault = on_fault
        self.msf = MultiSensorFusion(start, 0.0, params)
        self.last_gnss: GnssFix | None = None
        self.rejected_in_row = 0
        self._accepted_t: float | None = None
        self._rejected_fault = False
        self.fixes_refused = 0
        """Fixes refused as unusable or by the MSF's gate, over the run."""
        self._last: LocalizationEstimate | None = None
        self._held: LocalizationEstimate | None = None

    def step(self, t: float, truth: ChassisState, spoof_gnss: GnssSpoofer | None = None) -> LocalizationEstimate:
        if self._held is not None:
            return LocalizationEstimate(t, self._held.pose, self._held.cov)
        self.msf.predict(ImuSample(t, truth.accel, truth.yaw_rate))
        fixes = [GnssFix(t, fix.xy, fix.cov) for fix in self.gnss.take()]
        used = []
        if self._accepted_t is None:
            self._accepted_t = t
        for fix in fixes:
            if usable_fix(fix) and self.msf.update_gnss(fix):
                used.append(fix)
                self.rejected_in_row = 0
                self._accepted_t = t
            else:
                self.fixes_refused += 1
                self.rejected_in_row += 1
        self.last_gnss = used[-1] if used else None
        if not fixes and (why := self.gnss.stalled(t)) is not None:
            self.on_fault("gnss_stalled", why)
        if (not self._rejected_fault and self.rejected_in_row >= MAX_REJECTED_FIXES
                and t - self._accepted_t >= MAX_REJECTED_S):
            self._rejected_fault = True
            self.on_fault("gnss_rejected", f"{self.rejected_in_row} GNSS fixes in a row refused over "
                                           f"{t - self._accepted_t:.1f} s (unusable or outside the MSF's gate)")
        est = self.msf.estimate(t)
        pose = est.pose
        if not (math.isfinite(pose.x) and math.isfinite(pose.y) and math.isfinite(pose.yaw)
                and np.isfinite(est.cov).all()):
            self._held = self._last if self._last is not None else est
            self.on_fault("localization_lost", "the MSF pose is not finite; holding the last finite estimate")
            return LocalizationEstimate(t, self._held.pose, self._held.cov)
        self._last = est
        return est
