"""LD3-NaiveAR (paper §5.3): LD3's detection; on alarm, brake at the maximum deceleration while still
steering on the MSF output (like Apollo's in-lane-stop emergency planning)."""

from __future__ import annotations

import logging

from testbed.defense.base import Defense, DefenseStatus, Mode
from testbed.defense.config import DefenseConfig
from testbed.defense.faults import FaultLog
from testbed.defense.monitor import LaneConsistencyMonitor
from testbed.localization.estimate import LocalizationEstimate
from testbed.perception.detection import LaneDetection
from tracks.map_api import SemanticMap
from tracks.pose import Pose

logger = logging.getLogger(__name__)


class NaiveArDefense(Defense):
    """Same detector as LD3; the response trusts MSF for steering and stops at `max_decel`."""

    name = "ld3-naive-ar"

    def __init__(self, config: DefenseConfig) -> None:
        self.config = config
        self.faults = FaultLog(logger)
        self.monitor = LaneConsistencyMonitor(config.b, config.tau, config.existence_threshold, self.faults)
        self.detection_time: float | None = None

    @property
    def mode(self) -> Mode:
        return "normal" if self.detection_time is None else "ar"

    @property
    def stop_decel(self) -> float | None:
        return None if self.detection_time is None else self.config.max_decel

    def on_lane_detection(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> None:
        if self.detection_time is None and self.monitor.step(ld, msf, smap):
            self.detection_time = ld.timestamp
            logger.info("ld3-naive-ar: attack detected at t=%.3f", ld.timestamp)

    def pose_for_control(self, msf: LocalizationEstimate, smap: SemanticMap) -> Pose:
        return msf.pose

    def status(self) -> DefenseStatus:
        return DefenseStatus(
            detected=self.detection_time is not None,
            detection_time=self.detection_time,
            cusum=self.monitor.detector.statistic,
            d_msf=self.monitor.d_msf,
            d_ld=self.monitor.d_ld,
        )
