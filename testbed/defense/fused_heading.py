"""Heading of LD3's fused pose in attack response (`[defense] heading`; Alg. 2 leaves it open).

- "msf": the MSF yaw (the paper mode; FusionRipper biases it, and the controller aligns that bias).
- "lane": the lane heading at the MSF pose's centreline point (the car is assumed parallel to the lane).
- "ld": the lane heading plus the vehicle's heading relative to the lane read off the detected lines,
  ψ = −atan(c1) averaged over the valid lines, clamped to ±clamp (a bound on what a road patch that bends
  the lines can steer). Between detections ψ follows the change of the MSF yaw relative to the lane,
  which over 50 ms is the gyro's doing, not the attacker's.
- "fused": the safety-driven mean of the two relative headings, ψ = (ψ_MSF / R_MSF + ψ_LD / R_LD) /
  (1 / R_MSF + 1 / R_LD) with Alg. 4's uncertainties of the last fusion step, so the heading follows the
  source the deviation fusion trusts (the lines alone when R_MSF is infinite).

In fail-closed mode the LD3 response passes the dead-reckoned yaw where "MSF yaw" is written here (`own_yaw`): a
yaw no attacker moves, so when the fusion leaves the MSF out "fused" follows that yaw, not the lines' clamped
slope (which would hide a large heading error from the controller); so does "ld"/"fused" before any line the
response kept. With the own yaw, "ld" and "fused" turn it by the lines' disagreement with it (the lines' ψ less
the own yaw relative to the lane), bounded by `clamp` and by `turn_rate` times the time since the response's first
detection: the lines correct the gyro's slow drift, and lines rotated by a road patch steer no faster. Given the MSF's
heading (the fail-closed response), the lines turn the own yaw only into the interval spanned by the MSF's heading,
theirs and the lane's, widened by the first two's disagreement up to `yaw_margin`, as the dead-reckoned yaw is turned
before the alarm: against one attacked source the car heads as the other does, so neither turns the yaw out of it.
"""

from __future__ import annotations

import math

from testbed.defense.ld_deviation import line_distance
from testbed.defense.odometry import drift_allowance, into_heading_span
from testbed.lane_detection import LaneDetection
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose, wrap_angle

CROSSING_ITERATIONS = 3
"""Passes of `station_relative_heading`'s fixed point; each shrinks its error by |κ·c0 / (1 − κ·c0)| (0.3 on a
corner of radius 6 m)."""


def _valid_lines(ld: LaneDetection, existence_threshold: float) -> list[tuple[float, float]]:
    """(offset c0, slope c1) at x = 0 of the valid lines with a slope, left first."""
    return [(float(c[0]), float(c[1])) for c, p in ((ld.left, ld.left_prob), (ld.right, ld.right_prob))
            if math.isfinite(line_distance(c, p, existence_threshold)) and len(c) > 1 and math.isfinite(c[1])]


def line_relative_heading(ld: LaneDetection, existence_threshold: float) -> float | None:
    """Vehicle heading relative to the lane from the valid lines' slopes at x = 0 (rad, + left), or None."""
    lines = _valid_lines(ld, existence_threshold)
    return -math.atan(sum(slope for _, slope in lines) / len(lines)) if lines else None


def station_relative_heading(ld: LaneDetection, existence_threshold: float, smap: SemanticMap, pose: Pose,
                             lane: int | None) -> float | None:
    """The vehicle's heading relative to `lane` at the station of `pose` from the valid lines (rad, + left), or None.

    A line's slope at x = 0 is its heading where it crosses the car's lateral axis, c0·sin ψ of road behind the
    car's station for a line at offset c0 (ahead where c0·sin ψ < 0); on a curved lane the lane has turned by
    −κ·c0·sin ψ / (1 − κ·c0) between the two. So ψ is the lines' ψ₀ (`line_relative_heading`) plus the mean over
    the lines of the map's lane heading at the crossing less that at `pose`; the crossing is placed along the
    lateral axis of the lane heading plus ψ, never of the pose's own yaw (the MSF's, which the check judges), by
    fixed point from ψ₀. A crossing the map cannot place adds no turn."""
    lines = _valid_lines(ld, existence_threshold)
    if not lines:
        return None
    psi0 = -math.atan(sum(slope for _, slope in lines) / len(lines))
    if lane is None:
        lane = smap.project(pose).lane
    heading = smap.lane_point(pose, lane)[1]
    psi = psi0
    for _ in range(CROSSING_ITERATIONS):
        c, s = math.cos(heading + psi), math.sin(heading + psi)
        turn = 0.0
        for c0, _ in lines:
            try:  # noqa: SIM105 - a try costs less than contextlib.suppress, six times a call
                turn += wrap_angle(smap.lane_point(Pose(pose.x - c0 * s, pose.y + c0 * c, heading + psi), lane)[1]
                                   - heading)
            except OffMapError:
                pass
        psi = psi0 + turn / len(lines)
    return psi


class FusedHeading:
    """The fused pose's yaw for one heading source; `relative` is its last heading relative to the lane."""

    def __init__(self, source: str, clamp: float, existence_threshold: float, own_yaw: bool = False,
                 turn_rate: float = math.inf, yaw_margin: float = math.inf) -> None:
        self.source = source
        self.own_yaw = own_yaw
        self.clamp = clamp
        self.turn_rate = turn_rate
        """Own yaw: how fast the lines may turn the heading away from it since the first detection (rad/s)."""
        self.yaw_margin = yaw_margin
        """Own yaw with the MSF's heading given: the lines turn it only into the interval spanned by the MSF's heading,
        theirs and the lane's, widened by the first two's disagreement up to this (rad); infinite: towards the lines
        wherever it is."""
        self._start: float | None = None
        self.existence_threshold = existence_threshold
        self._ld_ref: tuple[float, float] | None = None  # (ψ from the lines, MSF yaw − lane heading) then
        self._ld_weight = 1.0
        self.relative: float | None = None

    def own_yaw_is_msf(self) -> None:
        """The yaw handed in is the MSF's after all (no odometry carried one): read the lines as without an own
        yaw from now on."""
        self.own_yaw = False
        self._ld_ref = None

    def on_detection(self, ld: LaneDetection, msf_yaw: float, lane_heading: float,
                     uncertainties: tuple[float, float] | None = None, lines_kept: bool = True,
                     msf_heading: float | None = None) -> None:
        """Read ψ off a new detection ("ld", "fused"); a detection without a valid line, or whose lines the
        response left out (`lines_kept` false), keeps the last ψ. `uncertainties` = (R_MSF, R_LD) of the fusion
        step, which "fused" weighs the headings by."""
        if self.source not in ("ld", "fused"):
            return
        if self._start is None:
            self._start = ld.timestamp
        psi = line_relative_heading(ld, self.existence_threshold) if lines_kept else None
        if psi is not None and self.own_yaw:
            bound = min(self.clamp, drift_allowance(self.turn_rate, ld.timestamp - self._start))
            own = wrap_angle(msf_yaw - lane_heading)
            target = psi
            if msf_heading is not None and math.isfinite(msf_heading) and math.isfinite(self.yaw_margin):
                msf_rel = wrap_angle(msf_heading - lane_heading)
                target = into_heading_span(own, msf_rel, psi, self.yaw_margin)
            self._ld_ref = (min(max(target - own, -bound), bound), own)
        elif psi is not None:
            self._ld_ref = (self._clamped(psi), wrap_angle(msf_yaw - lane_heading))
        if self.source == "fused" and uncertainties is not None:
            r_msf, r_ld = uncertainties
            if math.isinf(r_msf):  # the MSF left out: its yaw is the attacker's, or the defense's own (odometry)
                self._ld_weight = 0.0 if self.own_yaw else 1.0
            else:
                self._ld_weight = r_msf / (r_msf + r_ld)

    def yaw(self, msf_yaw: float, lane_heading: float) -> float:
        """The fused pose's yaw at the current MSF yaw and lane heading."""
        if self.source == "msf":
            yaw = msf_yaw
        elif self.source == "lane":
            yaw = lane_heading
        elif self._ld_ref is None:  # no line read yet: the own yaw, or (the MSF's being the attacker's) the lane's
            yaw = msf_yaw if self.own_yaw else lane_heading
        elif self.own_yaw:  # the own yaw, turned by the lines' bounded disagreement with it at their last reading
            yaw = msf_yaw + self._ld_weight * self._ld_ref[0]
        else:
            psi_ld, msf_rel_then = self._ld_ref
            msf_rel = wrap_angle(msf_yaw - lane_heading)
            psi = self._clamped(psi_ld + wrap_angle(msf_rel - msf_rel_then))
            yaw = lane_heading + self._ld_weight * psi + (1.0 - self._ld_weight) * msf_rel
        self.relative = wrap_angle(yaw - lane_heading)
        return yaw

    def _clamped(self, psi: float) -> float:
        return min(max(psi, -self.clamp), self.clamp)
