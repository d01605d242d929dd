"""The defense contract the loop drives: fed lane detections, GNSS fixes and commands, it answers
which pose the controller uses and whether (and how hard) to stop.

No method lets an exception escape on bad input (NaN poses, missing lane lines, off-map queries):
implementations log the case and handle it as their algorithm says.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Literal

import numpy as np

from testbed.defense.faults import FaultRecord
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import SemanticMap
from tracks.pose import Pose

Mode = Literal["normal", "ar"]


@dataclass(frozen=True)
class DefenseStatus:
    """A snapshot for logs and plots; None where the defense has no such quantity (yet)."""

    detected: bool
    detection_time: float | None = None
    cusum: float | None = None
    d_msf: float | None = None
    d_ld: float | None = None
    fused_dev: float | None = None
    r_msf: float | None = None
    r_ld: float | None = None
    kalman_gain_msf: float | None = None
    kalman_gain_ld: float | None = None
    heading_rel: float | None = None
    """Heading of the pose handed to control relative to the lane (rad, + left), in attack response."""
    alarm_check: str | None = None
    """Which of the defense's checks raised the alarm (docs/outputs.md, `alarm_check`); None before an alarm or
    where the defense has one check only."""


class Defense(ABC):
    """One defense: normal mode until its detector alarms, then attack response ("ar") for good."""

    name: str

    @property
    @abstractmethod
    def mode(self) -> Mode: ...

    @property
    @abstractmethod
    def stop_decel(self) -> float | None:
        """None while normal; the attack-response deceleration (m/s², > 0) once alarmed."""

    @abstractmethod
    def on_lane_detection(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> None:
        """A new lane detection (20 Hz) with the latest MSF estimate."""

    def on_gnss(self, t: float, xy: np.ndarray, cov: np.ndarray) -> None:  # noqa: B027 - optional hook
        """A raw (possibly spoofed) GNSS fix (10 Hz): world (x, y) and its 2×2 covariance."""

    def on_command(self, t: float, steer: float, accel: float, speed: float) -> None:  # noqa: B027
        """The command just sent (every control tick): road-wheel steer (rad), accel (m/s²), measured speed (m/s)."""

    def on_odometry(self, t: float, speed: float, yaw_rate: float) -> None:  # noqa: B027 - optional hook
        """Chassis odometry at the start of every control tick: speed (m/s), yaw rate (rad/s, + left; its mean over
        the period ending at `t` where the chassis measures it, `ChassisState.odometry_yaw_rate`)."""

    def odometry_bias(self) -> float | None:
        """Odometry's yaw-rate error per metre travelled as the defense estimated it (rad/m); None where it keeps no
        estimate."""
        return None

    def odometry_yaw_rate(self, speed: float, yaw_rate: float) -> float:
        """The chassis yaw rate with the defense's estimate of its bias taken out (rad/s; as reported for a defense
        that keeps none): what the loop's lane tracker and lateral controller read."""
        return yaw_rate

    @abstractmethod
    def pose_for_control(self, msf: LocalizationEstimate, smap: SemanticMap) -> Pose:
        """The pose the controller tracks with: MSF normally, the defense's own estimate in AR."""

    @abstractmethod
    def status(self) -> DefenseStatus: ...

    @property
    def alarm_threshold(self) -> float | None:
        """The threshold its `status().cusum` statistic alarms above (None: no such statistic)."""
        return None

    def fault_records(self) -> list[FaultRecord]:
        """The bad or degraded inputs it handled so far, one record per kind (none for a defense without)."""
        return []


class LatchingDefense(Defense):
    """The mode and stop logic LD3, NaiveAR and SAVIOR share: normal until `detection_time` is set, then
    attack response for good, stopping in lane at `response_decel`."""

    detection_time: float | None = None

    @property
    @abstractmethod
    def response_decel(self) -> float:
        """Deceleration of the attack-response stop (m/s², > 0)."""

    @property
    def mode(self) -> Mode:
        return "normal" if self.detection_time is None else "ar"

    @property
    def stop_decel(self) -> float | None:
        return None if self.detection_time is None else self.response_decel
