"""LD3's detection front end as a defense: normal until Alg. 1's CUSUM on the MSF/LD deviations (Alg. 3)
alarms, attack response for good after that. LD3 and NaiveAR share it and differ only in the response.
Chassis odometry reaches the monitor's dead-reckoned pose (fail-closed mode)."""

from __future__ import annotations

import logging

from testbed.defense.attack_detection import Cusum, LaneConsistencyMonitor
from testbed.defense.base import DefenseStatus, LatchingDefense
from testbed.defense.config import DefenseConfig
from testbed.defense.faults import FaultLog, FaultRecord
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import SemanticMap

logger = logging.getLogger(__name__)


class Ld3AlarmedDefense(LatchingDefense):
    """LD3 detection; once alarmed, mode "ar" and a stop at `response_decel`."""

    def __init__(self, config: DefenseConfig) -> None:
        self.config = config
        self.faults = FaultLog(logger)
        self.monitor = LaneConsistencyMonitor(config.b, config.tau, config.existence_threshold, self.faults,
                                              fail_closed=config.fail_closed,
                                              heading=Cusum(config.heading_b, config.heading_tau))
        self.detection_time: float | None = None

    @property
    def alarm_threshold(self) -> float | None:
        return self.config.tau

    def on_odometry(self, t: float, speed: float, yaw_rate: float) -> None:
        self.monitor.on_odometry(t, speed, yaw_rate)

    def fault_records(self) -> list[FaultRecord]:
        return self.faults.records()

    def _detect(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> bool:
        """One detection update while normal; True on the update that raises the alarm."""
        if self.detection_time is not None or not self.monitor.step(ld, msf, smap):
            return False
        self.detection_time = ld.timestamp
        logger.info("%s: attack detected at t=%.3f (S=%.3f)", self.name, ld.timestamp, self.monitor.detector.statistic)
        return True

    def status(self) -> DefenseStatus:
        return DefenseStatus(
            detected=self.detection_time is not None,
            detection_time=self.detection_time,
            cusum=self.monitor.detector.statistic,
            d_msf=self.monitor.d_msf,
            d_ld=self.monitor.d_ld,
        )
