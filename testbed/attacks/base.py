"""The attack contract the loop drives: what an attacker sees each tick and the four places it may act.

An attack may spoof GNSS fixes before the MSF fuses them, tamper with the MSF output, tamper with the
lane detector's output, or paint the road. Every hook defaults to the identity; `state()` reports the
attack's stage, switch time and current lateral offset (signed, + left) for trajectory.csv/summary.json.
Each attack declares the `capabilities` it acts through (its threat model); an adaptive attack may also read
what a white-box attacker knows (`WhiteBox`: the map, the defense's public parameters, the rates), handed to
`know()` once before the run starts.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.sensors import GnssFix
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose, wrap_angle


@dataclass(frozen=True)
class AttackerView:
    """What a tailgating attacker sees: time, the victim's true pose, signed physical lane deviation."""

    t: float
    true_pose: Pose
    phys_dev: float
    lane_heading: float
    speed: float


@dataclass(frozen=True)
class WhiteBox:
    """What a white-box attacker knows before the run: the semantic map and the victim's lane, the LiDAR
    locator's feature quality at a world point, the defense's public parameters (`defense`: CUSUM `b`, `tau`
    and the rest of its `[defense]` table), the lane detector's and the control loop's rates (Hz), and the
    victim's lateral controller (its model, gains and period; read, never stepped)."""

    smap: SemanticMap
    lane: int
    defense: Any
    detector_hz: float
    control_hz: float
    lidar_quality: Callable[[float, float], float] = lambda x, y: 1.0
    controller: Any = None

    @property
    def ticks_per_detection(self) -> int:
        """Control ticks from one lane detection to the next (the loop's camera period in ticks)."""
        return max(1, round(self.control_hz / self.detector_hz))

    def detection_tick(self, t: float) -> bool:
        """Whether the loop runs a lane detection on the control tick at `t` (ticks counted from t = 0)."""
        return round(t * self.control_hz) % self.ticks_per_detection == 0


def left_normal(heading: float) -> np.ndarray:
    """Unit vector pointing left of a direction of travel `heading` (rad)."""
    return np.array([-math.sin(heading), math.cos(heading)])


def shift_lines(ld: LaneDetection, offset: float, slope: float = 0.0) -> LaneDetection:
    """`ld` with both lines moved by −`offset` (the car appears `offset` m further left, + left) and their
    slope c1 raised by `slope`."""

    def moved(c: np.ndarray | None) -> np.ndarray | None:
        if c is None:
            return None
        c = c.copy()
        c[0] -= offset
        if len(c) > 1:
            c[1] += slope
        return c

    return dataclasses.replace(ld, left=moved(ld.left), right=moved(ld.right))


def msf_error(est: LocalizationEstimate, view: AttackerView, whitebox: WhiteBox) -> tuple[float, float]:
    """The MSF's own error as an attacker who sees the true pose reads it before tampering: its lane deviation
    less the true one (m, + left) and its yaw less the true yaw (rad); OffMapError where the map cannot place it."""
    lateral = float(whitebox.smap.lane_dev(est.pose, whitebox.lane)) - view.phys_dev
    return lateral, wrap_angle(est.pose.yaw - view.true_pose.yaw)


def sent_estimate(est: LocalizationEstimate, view: AttackerView, whitebox: WhiteBox, offset: float, yaw: float,
                  cancel: bool = True) -> LocalizationEstimate:
    """`est` moved `offset` m left of the lane and its yaw by `yaw` (rad); with `cancel` the MSF's own error is
    taken out first, so the defense sees exactly the attacker's input (a pose the map cannot place keeps it)."""
    error = (0.0, 0.0)
    if cancel and est.pose.is_finite():
        with contextlib.suppress(OffMapError):
            error = msf_error(est, view, whitebox)
    moved = shift_pose(est.pose, view.lane_heading, offset - error[0])
    return LocalizationEstimate(est.t, Pose(moved.x, moved.y, moved.yaw + (yaw - error[1])), est.cov)


def shift_pose(pose: Pose, heading: float, offset: float) -> Pose:
    """`pose` moved `offset` metres to the left (+) or right (−) of a direction of travel `heading`."""
    n = left_normal(heading)
    return Pose(pose.x + offset * float(n[0]), pose.y + offset * float(n[1]), pose.yaw)


class Attack(ABC):
    """One attack: hooks default to the identity; subclasses override the ones their threat model uses."""

    name: str = ""
    capabilities: ClassVar[frozenset[ThreatCapability]] = frozenset()
    """Where the attack acts; the hooks it overrides must lie within them."""

    def __init__(self, start_time: float) -> None:
        if not (math.isfinite(start_time) and start_time >= 0):
            raise UserError(f"attack start must be a time >= 0 s, got {start_time}")
        self.start_time = start_time
        self.whitebox: WhiteBox | None = None

    @property
    def threat_model(self) -> frozenset[ThreatCapability]:
        """The capabilities this attack acts through (a composition: its members' union)."""
        return self.capabilities

    def know(self, whitebox: WhiteBox) -> None:
        """What a white-box attacker knows, handed over once before the first tick."""
        self.whitebox = whitebox

    def spoof_gnss(self, fix: GnssFix, view: AttackerView) -> GnssFix:
        return fix

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        return est

    def tamper_ld(self, ld: LaneDetection, view: AttackerView) -> LaneDetection:
        return ld

    def painters(self) -> list[Any]:
        """Road-texture painters (only the road-patch attack has any)."""
        return []

    @abstractmethod
    def state(self) -> dict[str, Any]:
        """{'stage': str, 'switch_time': float | None, 'offset': float (m, + left)}."""

    @abstractmethod
    def describe(self) -> dict[str, Any]:
        """The attack spec as a JSON-able object: {'kind': ..., parameters...}."""
