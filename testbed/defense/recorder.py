"""A passive detection observer for offline (b, τ) sweeps of LD3 and SAVIOR (ROC curves).

`DetectionRecorder` is a defense that never alarms and never responds, so the vehicle drives exactly as
with no defense. It logs:

- LD3: every (D_MSF, D_LD) pair that Alg. 1's CUSUM would be fed, produced by the paper mode's front end
  (`LaneConsistencyMonitor` with fail_closed = False: Alg. 3, intersection gating, skipped updates), with a
  new segment after every intersection (where that detector resets S);
- SAVIOR: its raw inputs in arrival order: the first finite MSF estimate handed to it with a lane
  detection (SAVIOR's EKF starts there), every GNSS fix with its covariance, every command with the
  measured speed. `replay_savior` (testbed.defense.roc) re-runs SAVIOR's EKF on them with any bicycle
  coefficients.

Neither detector changes anything before its first alarm, so the first alarm of CUSUM(b, τ) on the
logged series is exactly the one the closed-loop paper-mode defense with (b, τ) would have raised; the
fail-closed default also feeds S through intersections, line gaps and off-map poses and never resets it.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from testbed.defense.attack_detection import LaneConsistencyMonitor, Ld3Detector
from testbed.defense.base import DefenseStatus
from testbed.defense.faults import FaultLog
from testbed.defense.ld_deviation import LdLines
from testbed.defense.no_defense import NoDefense
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import SemanticMap

logger = logging.getLogger(__name__)


class _LoggingDetector(Ld3Detector):
    """Alg. 1's detector with τ = ∞ that hands every residual pair and every reset to `log`."""

    def __init__(self, log: DetectionLog, clock: list[float]) -> None:
        super().__init__(b=0.0, tau=math.inf)
        self._log = log
        self._clock = clock

    def update(self, d_msf: float, d_ld: float) -> bool:
        self._log.ld3.append((self._clock[0], d_msf, d_ld, self._log.segment))
        return super().update(d_msf, d_ld)

    def reset(self) -> None:
        self._log.segment += 1
        super().reset()


@dataclass
class DetectionLog:
    """The recorded series. Rows: ld3 (t, D_MSF, D_LD, segment); gnss (t, x, y, c_xx, c_xy, c_yy);
    commands (t, steer, accel, speed); init (t, x, y, yaw, var_x, var_y, var_yaw), at most one row."""

    ld3: list[tuple[float, float, float, int]] = field(default_factory=list)
    gnss: list[tuple[float, ...]] = field(default_factory=list)
    commands: list[tuple[float, float, float, float]] = field(default_factory=list)
    init: list[tuple[float, ...]] = field(default_factory=list)
    segment: int = 0

    def arrays(self) -> dict[str, np.ndarray]:
        return {
            "ld3": np.array(self.ld3, dtype=float).reshape(-1, 4),
            "gnss": np.array(self.gnss, dtype=float).reshape(-1, 6),
            "commands": np.array(self.commands, dtype=float).reshape(-1, 4),
            "init": np.array(self.init, dtype=float).reshape(-1, 7),
        }

    def save(self, path: Path) -> None:
        np.savez_compressed(path, **self.arrays())


def load_detection_log(path: Path) -> dict[str, np.ndarray]:
    """The arrays `DetectionLog.save` wrote: keys ld3, gnss, commands, init."""
    with np.load(path) as data:
        return {k: data[k] for k in ("ld3", "gnss", "commands", "init")}


class DetectionRecorder(NoDefense):
    """Observes like LD3 and SAVIOR, logs their detector inputs, drives like no defense."""

    def __init__(self, existence_threshold: float = 0.5, ld_lines: LdLines = "nearer") -> None:
        self.log = DetectionLog()
        self._clock = [math.nan]
        self.monitor = LaneConsistencyMonitor(0.0, math.inf, existence_threshold, FaultLog(logger),
                                              fail_closed=False, ld_lines=ld_lines)
        self.monitor.detector = _LoggingDetector(self.log, self._clock)

    def on_lane_detection(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> None:
        self._clock[0] = ld.timestamp
        self.monitor.step(ld, msf, smap)
        if not self.log.init and msf.pose.is_finite():
            cov = np.asarray(msf.cov, dtype=float)
            var = np.diag(cov) if cov.shape == (3, 3) and np.isfinite(cov).all() else np.ones(3)
            p = msf.pose
            self.log.init.append((msf.t, p.x, p.y, p.yaw, *(float(v) for v in var)))

    def on_gnss(self, t: float, xy: np.ndarray, cov: np.ndarray) -> None:
        xy = np.asarray(xy, dtype=float).ravel()
        cov = np.asarray(cov, dtype=float)
        self.log.gnss.append((t, float(xy[0]), float(xy[1]), float(cov[0, 0]), float(cov[0, 1]), float(cov[1, 1])))

    def on_command(self, t: float, steer: float, accel: float, speed: float) -> None:
        self.log.commands.append((t, steer, accel, speed))

    def status(self) -> DefenseStatus:
        return DefenseStatus(detected=False, cusum=None, d_msf=self.monitor.d_msf, d_ld=self.monitor.d_ld)
