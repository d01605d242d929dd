"""Localization on a vehicle: the MSF propagated by what the chassis reports (longitudinal acceleration and yaw
rate, its IMU) and updated by GNSS fixes from the NMEA reader; no LiDAR locator. A stalled GNSS stream is
reported through `on_fault` instead of driving on dead reckoning."""

from __future__ import annotations

from collections.abc import Callable

from hil.nmea_gnss import NmeaGnssReader
from testbed.chassis import ChassisState
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.msf import MsfParams, MultiSensorFusion
from testbed.localization.sensors import GnssFix, ImuSample
from testbed.localization.stack import GnssSpoofer
from tracks.pose import Pose


class MeasuredLocalization:
    """The loop's `Localization` from real sensors: `step` fuses the chassis's motion and the fixes that arrived
    since the last tick (stamped at this tick); `start` is the first pose (from the first fix and the map)."""

    def __init__(self, gnss: NmeaGnssReader, start: Pose, on_fault: Callable[[str, str], None],
                 params: MsfParams | None = None) -> None:
        self.gnss = gnss
        self.on_fault = on_fault
        self.msf = MultiSensorFusion(start, 0.0, params)
        self.last_gnss: GnssFix | None = None

    def step(self, t: float, truth: ChassisState, spoof_gnss: GnssSpoofer | None = None) -> LocalizationEstimate:
        self.msf.predict(ImuSample(t, truth.accel, truth.yaw_rate))
        fixes = [GnssFix(t, fix.xy, fix.cov) for fix in self.gnss.take()]
        for fix in fixes:
            self.msf.update_gnss(fix)
        self.last_gnss = fixes[-1] if fixes else None
        if not fixes and (why := self.gnss.stalled(t)) is not None:
            self.on_fault("gnss_stalled", why)
        return self.msf.estimate(t)
