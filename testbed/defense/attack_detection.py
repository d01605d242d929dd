"""LD3 attack detection (paper Alg. 1): per lane detection, D_MSF = map lane deviation of the latest MSF
pose, D_LD by Alg. 3 with the map's lane width, and a one-sided CUSUM on D_MSF − D_LD:
S_i = max(0, S_{i-1} + |r_i| − b), alarm when S_i > τ (lines 6–10).

Paper mode: detection is disabled while the MSF pose is inside an intersection (no lane markings) and
resumes after it with S reset and Alg. 3's memory cleared; a detection with a non-finite pose, an off-map
query, or no D_LD yet is skipped and logged.

Fail-closed mode (the default): an MSF pose the map cannot place feeds the CUSUM the lane width as its residual. A pose
dead-reckoned from odometry (`DeadReckoning`), anchored at every detection where MSF and lines agree within b (the MSF
pose moved across the lane to D_LD; the yaw carried by the gyro and pulled into the interval spanned by the MSF's and
the lines' headings relative to the lane and the lane's own: the car heads as the source not attacked does, so lines a
road patch bends, slowly or not, do not turn the yaw the response will steer on out of it, nor, with an honest heading
erring to the same side, past the lane's heading), stands in for the lines where they are absent: inside intersections
(judged at that pose) and on detections without a valid line the residual is D_MSF − D_odometry, S is never reset, and
only Alg. 3's memory is cleared after a zone. Lines apart from both the MSF and the dead-reckoned pose where those two
agree (`lines_gate`, across the lane or in heading) are astray, and that detection is checked as one without lines: two
sources that agree outvote the third, so honest lines beside an attacked MSF are never set aside. Where the
MSF disagrees with the lines but the lines agree with the dead-reckoned pose within b, that pose is moved towards
them at its own station, by no more than `line_rate` allows since its last anchor: an attacker who holds the
residual just above b cannot leave odometry to drift until the response takes it for the car's place, and an
attacker of the lines who ramps them away from a true MSF cannot drag odometry along. D_MSF is
measured against the lane of the dead-reckoned pose, so an MSF pose moved by a lane width does not agree with
the lines. Every skipped or degraded update is a fault. A second CUSUM (`heading`) checks the MSF's heading
relative to the lane against the lines' (against the dead-reckoned yaw where lines are absent): an MSF yaw
biased with a true position moves no deviation Alg. 1 compares, yet steers the car off the centreline. A third
CUSUM (`along`) checks the MSF pose's position along the lane against the dead-reckoned pose's: an MSF pose moved
along the lane with its lateral offset and relative heading kept moves neither deviation, yet hands the controller
another station's curvature. The dead-reckoned pose takes only the share `along_gain` of the MSF's station at each
anchor, so odometry, not the MSF, carries the station between anchors; a drift slower than about
along_b · along_gain · detection rate stays under the check (docs/decisions.md).

`Ld3Detector` and `cusum_alarm_index` run the same test on logged (D_MSF, D_LD) traces, e.g. to sweep b and τ
for ROC curves.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from testbed.defense.faults import FaultLog
from testbed.defense.fused_heading import station_relative_heading
from testbed.defense.fusion import pose_on_lane
from testbed.defense.ld_deviation import LdDeviation, LdLines
from testbed.defense.odometry import (
    CurvatureBias,
    DeadReckoning,
    drift_allowance,
    into_heading_span,
    into_span,
    step_toward,
)
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose, wrap_angle


class Cusum:
    """One-sided CUSUM over residual magnitudes; latches at the first alarm (Alg. 1 `break`)."""

    def __init__(self, b: float, tau: float) -> None:
        self.b = b
        self.tau = tau
        self.statistic = 0.0
        self.alarmed = False

    def update(self, residual: float) -> bool:
        """Feed one residual; True once S > τ. After the alarm S is frozen at its alarm value."""
        if not self.alarmed:
            self.statistic = max(0.0, self.statistic + abs(residual) - self.b)
            self.alarmed = self.statistic > self.tau
        return self.alarmed

    def reset(self) -> None:
        """S back to 0 and the alarm cleared (paper mode, after a zone where detection is disabled)."""
        self.statistic = 0.0
        self.alarmed = False


def cusum_alarm_index(residuals: Iterable[float], b: float, tau: float) -> int | None:
    """Index of the first residual at which CUSUM(b, τ) alarms, or None: for offline (b, τ) sweeps."""
    s = 0.0
    for i, r in enumerate(residuals):
        s = max(0.0, s + abs(r) - b)
        if s > tau:
            return i
    return None


class Ld3Detector:
    """Consistency check between the MSF and LD lateral deviations; latches at the first alarm."""

    def __init__(self, b: float = 0.6, tau: float = 0.1) -> None:
        self.cusum = Cusum(b, tau)

    def update(self, d_msf: float, d_ld: float) -> bool:
        """Feed one pair of deviations (m); True once under attack."""
        return self.cusum.update(d_msf - d_ld)

    @property
    def statistic(self) -> float:
        return self.cusum.statistic

    @property
    def alarmed(self) -> bool:
        return self.cusum.alarmed

    def reset(self) -> None:
        self.cusum.reset()


ANCHOR_YAW_GAIN = 0.1
"""Share of the gap between the dead-reckoned yaw and the lines' heading closed per agreeing detection: the
detector's heading noise averaged over about ten detections (0.5 s at 20 Hz)."""
TRUSTED_SHARE = 0.5
"""Share of b within which D_MSF and D_LD agree for `LaneConsistencyMonitor.trusted` to take the dead-reckoned pose:
lines that ramp away from a true MSF pull the dead-reckoned pose up to b before the CUSUM sees them, the trusted
pose half that. Between those detections the trusted pose is kept within the same share of b of the interval between
D_MSF and D_LD: against one attacked source the car is at the other, so the trusted pose comes no farther from it
than the two sources are apart, however long the attacker holds them apart."""
UNPLACED_RESIDUAL_M = 3.5
"""Residual fed for an MSF pose the map cannot place while the map has given no lane width yet (m): a lane."""


class LaneConsistencyMonitor:
    """Alg. 1 with intersection gating. After the alarm, `ego_lane` is the lane the MSF pose was on at the last
    detection where D_MSF and D_LD agreed within b (the MSF lane at the alarm if they never did): an attacker
    can move the MSF pose farther than b from where the lines put the car only by raising the statistic, so
    that lane is the car's own even when the alarm comes on an MSF pose already beyond half a lane.
    `fail_closed` selects the fail-closed front end (module docstring) over the paper's."""

    def __init__(self, b: float, tau: float, existence_threshold: float, faults: FaultLog, *,
                 fail_closed: bool, heading: Cusum | None = None, along: Cusum | None = None,
                 along_gain: float = 1.0, line_rate: float = math.inf, line_yaw_rate: float = math.inf,
                 yaw_margin: float = 0.0, yaw_agreement: tuple[float, float] = (0.0, 0.0), bias_span: float = 0.0,
                 lever: float = 0.0, lines_gate: tuple[float, float, float] = (math.inf, math.inf, math.inf),
                 ld_lines: LdLines = "nearer") -> None:
        self.detector = Ld3Detector(b, tau)
        self.heading = heading if heading is not None else Cusum(0.0, math.inf)
        """The fail-closed heading check's CUSUM on |ψ_MSF − ψ_lines| (rad); never alarms when not given."""
        self.along = along if along is not None else Cusum(0.0, math.inf)
        """The fail-closed along-lane check's CUSUM on |s_MSF − s_odometry| (m); never alarms when not given."""
        self.along_gain = along_gain
        self.line_rate = line_rate
        """How fast the lines alone (the MSF disagreeing) may move the dead-reckoned pose across the lane (m/s)."""
        self.line_yaw_rate = line_yaw_rate
        """How fast the lines' heading may turn the dead-reckoned yaw (rad/s)."""
        self.yaw_margin = yaw_margin
        """How far outside the interval between the sources' headings the dead-reckoned yaw may sit unturned where
        they disagree that much or more (rad)."""
        self.lines_gate = lines_gate
        """(m, rad, rad): a detection whose lines disagree with the MSF (beyond b, or beyond the heading check's b) and
        lie farther than this from the dead-reckoned pose, across the lane or in heading relative to it (the third for
        lines within b of both across the lane), is astray: the MSF is checked against odometry on it, as where lines
        are absent."""
        self._anchor_time: float | None = None
        self.ld_dev = LdDeviation(existence_threshold, ld_lines)
        self.faults = faults
        self.fail_closed = fail_closed
        self.odometry = DeadReckoning(lever)
        """The dead-reckoned pose (`lever`: the pose's reference point ahead of the rear axle, m)."""
        self.trusted = DeadReckoning(lever)
        """The dead-reckoned pose as of the last detection where D_MSF and D_LD agreed within `TRUSTED_SHARE` of b,
        carried by odometry since and kept near the interval between D_MSF and D_LD (`TRUSTED_SHARE`): where the
        response's reference starts (`Ld3Defense`)."""
        self.yaw_agreement = yaw_agreement
        """How closely the MSF's and the lines' headings relative to the lane must agree (rad), D_MSF and D_LD within
        b, for the MSF's yaw to teach `yaw_bias`: before its first estimate (the lines tracked on the biased yaw
        rate until then) and after."""
        self.yaw_bias = CurvatureBias(bias_span, 0.5 * line_yaw_rate if math.isfinite(line_yaw_rate) else 0.0)
        """Odometry's yaw-rate error per metre, learnt from the MSF's yaw where MSF and lines fully agree; the
        dead-reckoned pose is carried on the corrected yaw rate (what is under half `line_yaw_rate` left to the
        lines' turn of the yaw). Frozen at the alarm."""
        self.d_msf: float | None = None
        self.d_ld: float | None = None
        self.fresh_d_ld: float | None = None
        """D_LD of the last detection when a line seen in it gave one (None when absent or reused)."""
        self.in_intersection = False
        self.ego_lane: int | None = None
        self.alarm_check: str | None = None
        """Which check raised the alarm and against what: `lateral-` (Alg. 1), `heading-` or `along-`, then `lines`,
        `odometry` or `unplaced` (an MSF pose the map cannot place, fed the lane width); None before an alarm."""
        self._agreed_lane: int | None = None
        self._width: float | None = None

    def on_odometry(self, t: float, speed: float, yaw_rate: float) -> None:
        """Carry the dead-reckoned pose to `t` on the bias-corrected yaw rate (fail-closed mode); a bad sample is a
        fault."""
        if not self.fail_closed:
            return
        corrected = self.yaw_bias.corrected(speed, yaw_rate)
        if self.odometry.on_odometry(t, speed, corrected):
            self.trusted.on_odometry(t, speed, corrected)
            self.yaw_bias.on_odometry(t, speed, yaw_rate)
        else:
            self.faults.report("bad-odometry", t, f"speed={speed}, yaw rate={yaw_rate}; sample skipped")

    @property
    def reckoned(self) -> Pose | None:
        """The dead-reckoned pose once anchored and carried by odometry, else None."""
        odo = self.odometry
        return odo.pose if odo.pose is not None and odo.samples > 0 else None

    def step(self, ld: LaneDetection, msf: LocalizationEstimate, smap: SemanticMap) -> bool:
        """One detection step; True at (and after) the alarm of either CUSUM."""
        if self.detector.alarmed or self.heading.alarmed or self.along.alarmed:
            return True
        self.fresh_d_ld = None
        if self.fail_closed:
            return self._step_fail_closed(ld, msf.pose, smap)
        return self._step_paper(ld, msf.pose, smap)

    def _step_paper(self, ld: LaneDetection, pose: Pose, smap: SemanticMap) -> bool:
        """Alg. 1 as the paper runs it: gated off in intersections, S reset after them, bad inputs skipped."""
        if not pose.is_finite():
            self.faults.report("nan-pose", ld.timestamp, f"MSF pose {pose} is not finite; update skipped")
            return False
        try:
            inside = smap.is_intersection(pose)
        except OffMapError as err:
            self.faults.report("off-map", ld.timestamp, f"is_intersection: {err}; update skipped")
            return False
        if inside:
            self.in_intersection = True
            return False
        if self.in_intersection:
            self.in_intersection = False
            self.detector.reset()
            self.ld_dev.reset()
        pair = self.deviations(ld, pose, smap)
        if pair is None:
            return False
        try:
            lane = smap.project(pose).lane
        except OffMapError as err:
            self.faults.report("off-map", ld.timestamp, f"project: {err}; ego lane left to the map")
            lane = None
        if abs(pair[0] - pair[1]) <= self.detector.cusum.b and lane is not None:
            self._agreed_lane = lane
        return self._update(*pair, lane, "lines")

    def _step_fail_closed(self, ld: LaneDetection, pose: Pose, smap: SemanticMap) -> bool:
        """Alg. 1 failing closed: an unplaceable MSF pose feeds a lane width, missing lines the odometry check,
        and an agreement with the lines re-anchors the dead-reckoned pose."""
        t = ld.timestamp
        reckoned = self.reckoned
        lane = self._lane_of(t, reckoned, smap)
        d_msf = self.msf_deviation(t, pose, smap, lane)
        if d_msf is None:
            return self._update(self._unplaced_residual(reckoned, lane, smap), 0.0, lane, "unplaced")
        self.d_msf = d_msf
        if lane is None:
            lane = smap.project(pose).lane
        if self._inside(t, reckoned if reckoned is not None else pose, smap):
            self.in_intersection = True
            return self._odometry_check(t, d_msf, pose.yaw, reckoned, lane, smap, "gated-zone",
                                        "no lane lines in the zone")
        if self.in_intersection:
            self.in_intersection = False
            self.ld_dev.reset()
        width = self._lane_width(t, pose, smap, lane)
        d_ld = None if width is None else self.ld_dev.update(ld, width)
        if d_ld is None or self.ld_dev.reused:
            return self._odometry_check(t, d_msf, pose.yaw, reckoned, lane, smap, "no-lane-lines",
                                        "no valid lane line")
        psi = station_relative_heading(ld, self.ld_dev.existence_threshold, smap, pose, lane)
        if reckoned is not None:
            astray = self._lines_astray(d_msf, d_ld, pose.yaw, psi, reckoned, smap, lane)
            if astray is not None:
                return self._odometry_check(t, d_msf, pose.yaw, reckoned, lane, smap, "lines-astray", astray)
        self.faults.clear()
        self.d_ld = self.fresh_d_ld = d_ld
        if reckoned is not None and self._check_along(pose, reckoned, smap, lane):
            return True
        b_lat = self.detector.cusum.b
        self._hold_trusted(d_msf, d_ld, TRUSTED_SHARE * b_lat, smap, lane)
        if abs(d_msf - d_ld) <= b_lat:
            self._agreed_lane = lane
            self._anchor(ld, pose, smap, lane, d_ld, agreed=True)
            if abs(d_msf - d_ld) <= TRUSTED_SHARE * b_lat:
                self.trusted.anchor(self.odometry.pose)
        elif reckoned is not None and abs((d_odo := float(smap.lane_dev(reckoned, lane))) - d_ld) <= b_lat:
            # the lines agree with odometry: its own station kept, moved towards the lines at `line_rate` at most
            since = t - self._anchor_time if self._anchor_time is not None else 0.0
            self._anchor(ld, reckoned, smap, lane, step_toward(d_odo, d_ld, drift_allowance(self.line_rate, since)),
                         msf_yaw=pose.yaw)
        if psi is not None and self._check_heading(pose.yaw - smap.lane_point(pose, lane)[1] - psi, lane, "lines"):
            return True
        return self._update(d_msf, d_ld, lane, "lines")

    def _lines_astray(self, d_msf: float, d_ld: float, msf_yaw: float, psi: float | None, reckoned: Pose,
                      smap: SemanticMap, lane: int) -> str | None:
        """Why the lines are astray (`lines_gate`): apart from both the MSF and the dead-reckoned pose, across the lane
        or in heading (beyond the third gate for lines within b of both across the lane: a heading misread; beyond
        the second for lines also moved across it); None when they are not. Two sources that agree outvote the third,
        so an MSF attacker cannot have honest lines set aside, and lines that left both are no evidence against the
        MSF."""
        gate, heading_gate, in_place_gate = self.lines_gate
        b = self.detector.cusum.b
        d_odo = float(smap.lane_dev(reckoned, lane))
        if abs(d_msf - d_odo) <= b and abs(d_ld - d_msf) > b and abs(d_ld - d_odo) > gate:
            return f"D_LD={d_ld:.3f} against D_MSF={d_msf:.3f} and odometry D={d_odo:.3f}"
        if psi is None:
            return None
        heading = smap.lane_point(reckoned, lane)[1]
        msf_rel, odo_rel = wrap_angle(msf_yaw - heading), wrap_angle(reckoned.yaw - heading)
        limit = in_place_gate if max(abs(d_ld - d_msf), abs(d_ld - d_odo)) <= b else heading_gate
        if (abs(wrap_angle(msf_rel - odo_rel)) <= heading_gate and abs(wrap_angle(msf_rel - psi)) > self.heading.b
                and abs(wrap_angle(odo_rel - psi)) > limit):
            return f"lines' heading {psi:.3f} against the MSF's {msf_rel:.3f} and odometry's {odo_rel:.3f} (rad)"
        return None

    def _check_heading(self, residual: float, lane: int | None, against: str) -> bool:
        """Feed the heading CUSUM the wrapped heading residual (rad) against `against`'s heading; True (and
        `ego_lane` fixed) on its alarm."""
        return self.heading.update(math.remainder(residual, math.tau)) and self._latch(lane, f"heading-{against}")

    def _check_along(self, pose: Pose, reckoned: Pose, smap: SemanticMap, lane: int) -> bool:
        """Feed the along CUSUM the MSF pose's distance along the lane from the dead-reckoned pose (m); True (and
        `ego_lane` fixed) on its alarm."""
        heading = smap.lane_point(reckoned, lane)[1]
        gap = (pose.x - reckoned.x) * math.cos(heading) + (pose.y - reckoned.y) * math.sin(heading)
        return self.along.update(gap) and self._latch(lane, "along-odometry")

    def _anchor(self, ld: LaneDetection, pose: Pose, smap: SemanticMap, lane: int, d_ld: float,
                agreed: bool = False, msf_yaw: float | None = None) -> None:
        """Re-anchor the dead-reckoned pose where MSF and lines agree: at the station the share `along_gain` of the way
        from its own to the MSF pose's (all the way for a first anchor), D_LD across the lane, the yaw pulled into the
        interval spanned by the MSF's heading (`msf_yaw`, else `pose`'s), the lines' and the lane's, relative to the
        lane, widened by the two sources' disagreement up to `yaw_margin` (`into_heading_span`), at `line_yaw_rate` at
        most (for a first anchor the middle of the MSF's, the lines' and the lane's relative headings, so one source
        off alone does not set it; the MSF yaw without lines): against one attacked source the car heads as the other
        does, so a yaw in that interval stays where the gyro carried it and neither source alone can turn it out of it,
        however slowly; the margin keeps the honest source's wandering heading from ratcheting it towards the other's.
        `agreed`: D_MSF and D_LD within b; where the MSF's heading (`pose.yaw`) also agrees with the lines' within
        `yaw_agreement`, the MSF's yaw teaches `yaw_bias` (not the lines' heading: an attacker of the lines alone then
        teaches nothing)."""
        reckoned = self.reckoned
        if reckoned is not None and self.along_gain < 1.0:
            g = self.along_gain
            pose = Pose(reckoned.x + g * (pose.x - reckoned.x), reckoned.y + g * (pose.y - reckoned.y), pose.yaw)
        point, heading = smap.lane_point(pose, lane)
        psi = station_relative_heading(ld, self.ld_dev.existence_threshold, smap, pose, lane)
        # how far the pose's heading relative to the lane is from the lines' (rad)
        off = math.inf if psi is None else abs(math.remainder(pose.yaw - heading - psi, math.tau))
        if agreed and off <= self.yaw_agreement[self.yaw_bias.estimated]:
            self.odometry.turn(self.yaw_bias.observe(pose.yaw))
        carried = self.odometry.pose
        msf_rel = wrap_angle((pose.yaw if msf_yaw is None else msf_yaw) - heading)
        if psi is None:
            yaw, gain = pose.yaw, 0.0
        elif carried is None or self._anchor_time is None:
            yaw, gain = heading + sorted((msf_rel, psi, 0.0))[1], ANCHOR_YAW_GAIN
        else:  # the gyro's yaw turned into the sources' interval by the gain's share, no faster than `line_yaw_rate`
            own = wrap_angle(carried.yaw - heading)
            turn = ANCHOR_YAW_GAIN * (into_heading_span(own, msf_rel, psi, self.yaw_margin) - own)
            limit = drift_allowance(self.line_yaw_rate, ld.timestamp - self._anchor_time)
            yaw, gain = carried.yaw + max(-limit, min(limit, turn)), 1.0
        self.odometry.anchor(pose_on_lane(point, heading, d_ld, yaw), gain)
        self._anchor_time = ld.timestamp

    def _hold_trusted(self, d_msf: float, d_ld: float, margin: float, smap: SemanticMap, lane: int) -> None:
        """Move the trusted pose across `lane`, at its own station and yaw, into [min(D_MSF, D_LD) − margin,
        max(D_MSF, D_LD) + margin] where it is outside (a pose the map cannot place is left as it is)."""
        pose = self.trusted.pose
        if pose is None:
            return
        try:
            d = float(smap.lane_dev(pose, lane))
            held = into_span(d, d_msf, d_ld, margin)
            if held != d:
                point, heading = smap.lane_point(pose, lane)
                self.trusted.anchor(pose_on_lane(point, heading, held, pose.yaw))
        except OffMapError:
            return

    def _update(self, d_msf: float, d_ref: float, lane: int | None, against: str) -> bool:
        """Feed the CUSUM D_MSF − D_ref, D_ref from `against` (the lines, odometry, or the lane width standing for
        an unplaced pose); True (and `ego_lane` fixed) on its alarm."""
        return self.detector.update(d_msf, d_ref) and self._latch(lane, f"lateral-{against}")

    def _latch(self, lane: int | None, check: str) -> bool:
        """At an alarm: fix `ego_lane` (the last agreed lane, else `lane`) and name the `check` that raised it; True."""
        self.ego_lane = self._agreed_lane if self._agreed_lane is not None else lane
        self.alarm_check = check
        return True

    def _lane_of(self, t: float, reckoned: Pose | None, smap: SemanticMap) -> int | None:
        """The lane of the dead-reckoned pose (None without one: the MSF pose's nearest lane is used)."""
        if reckoned is None:
            return None
        try:
            return smap.project(reckoned).lane
        except OffMapError as err:
            self.faults.report("odometry-off-map", t, f"dead-reckoned pose: {err}; lane left to the MSF pose")
            return None

    def _inside(self, t: float, pose: Pose, smap: SemanticMap) -> bool:
        """Whether `pose` is in an intersection; a pose the map cannot place is a fault and counts as outside."""
        try:
            return smap.is_intersection(pose)
        except OffMapError as err:
            self.faults.report("odometry-off-map", t, f"is_intersection: {err}; taken as outside")
            return False

    def _lane_width(self, t: float, pose: Pose, smap: SemanticMap, lane: int | None) -> float | None:
        """The map's width of `lane` at `pose`, or None (a fault) when it has no usable one."""
        try:
            width = float(smap.lane_width(pose, lane))
        except OffMapError as err:
            self.faults.report("off-map", t, f"lane_width: {err}; update skipped")
            return None
        if not (math.isfinite(width) and width > 0.0):
            self.faults.report("bad-map", t, f"lane width={width}; update skipped")
            return None
        self._width = width
        return width

    def _unplaced_residual(self, reckoned: Pose | None, lane: int | None, smap: SemanticMap) -> float:
        """The residual of an MSF pose the map cannot place: the lane width at the dead-reckoned pose, else
        the last width the map gave, else `UNPLACED_RESIDUAL_M`."""
        if reckoned is not None:
            try:
                width = float(smap.lane_width(reckoned, lane))
            except OffMapError:
                width = math.nan
            if math.isfinite(width) and width > 0.0:
                return width
        return self._width if self._width is not None else UNPLACED_RESIDUAL_M

    def _odometry_check(self, t: float, d_msf: float, msf_yaw: float, reckoned: Pose | None, lane: int,
                        smap: SemanticMap, kind: str, why: str) -> bool:
        """Lines absent: feed D_MSF − D_odometry, or skip the update (a fault either way)."""
        if reckoned is None:
            self.faults.report(kind, t, f"{why}; no dead-reckoned pose yet: update skipped")
            return False
        try:
            d_odo = float(smap.lane_dev(reckoned, lane))
        except OffMapError as err:
            self.faults.report("odometry-off-map", t, f"{why}; dead-reckoned pose: {err}; update skipped")
            return False
        self.faults.report(kind, t, f"{why}; D_MSF={d_msf:.3f} checked against odometry D={d_odo:.3f}")
        if self._check_heading(msf_yaw - reckoned.yaw, lane, "odometry"):
            return True
        return self._update(d_msf, d_odo, lane, "odometry")

    def msf_deviation(self, t: float, pose: Pose, smap: SemanticMap, lane: int | None) -> float | None:
        """D_MSF against `lane` (nearest lane when None), or None (a fault) when the map cannot place the pose."""
        if not pose.is_finite():
            self.faults.report("nan-pose", t, f"MSF pose {pose} is not finite")
            return None
        try:
            d_msf = float(smap.lane_dev(pose, lane))
        except OffMapError as err:
            self.faults.report("off-map", t, f"MSF pose: {err}")
            return None
        if not math.isfinite(d_msf):
            self.faults.report("bad-map", t, f"D_MSF={d_msf}")
            return None
        return d_msf

    def lines_deviation(self, ld: LaneDetection, width: float) -> float | None:
        """Alg. 3 on a detection in attack response: D_LD from a line seen in it, else None (a fault)."""
        d_ld = self.ld_dev.update(ld, width)
        if d_ld is None or self.ld_dev.reused:
            self.faults.report("no-lane-lines", ld.timestamp, "no valid lane line; no D_LD this detection")
            return None
        self.faults.clear()
        self.d_ld = d_ld
        return d_ld

    def ego_pair(self, t: float, pose: Pose, smap: SemanticMap) -> tuple[float, float] | None:
        """The alarm's (D_MSF, D_LD) with D_MSF measured against `ego_lane` (Alg. 1 measured it against the
        lane nearest the MSF pose); None when the map cannot answer."""
        if self.d_msf is None or self.d_ld is None:
            return None
        try:
            return float(smap.lane_dev(pose, self.ego_lane)), self.d_ld
        except OffMapError as err:
            self.faults.report("off-map", t, f"lane_dev on the ego lane at the alarm: {err}")
            return None

    def deviations(
        self, ld: LaneDetection, pose: Pose, smap: SemanticMap, lane: int | None = None
    ) -> tuple[float, float] | None:
        """(D_MSF, D_LD) against `lane` (nearest lane when None), or None when it cannot be formed."""
        t = ld.timestamp
        if not pose.is_finite():
            self.faults.report("nan-pose", t, f"MSF pose {pose} is not finite; update skipped")
            return None
        try:
            d_msf = float(smap.lane_dev(pose, lane))
            width = float(smap.lane_width(pose, lane))
        except OffMapError as err:
            self.faults.report("off-map", t, f"lane_dev/lane_width: {err}; update skipped")
            return None
        if not (math.isfinite(d_msf) and math.isfinite(width) and width > 0.0):
            self.faults.report("bad-map", t, f"D_MSF={d_msf}, lane width={width}; update skipped")
            return None
        d_ld = self.ld_dev.update(ld, width)
        if d_ld is None:
            self.faults.report("no-lane-lines", t, "no valid lane line yet; update skipped")
            return None
        if self.ld_dev.reused:
            self.faults.report("no-lane-lines", t, f"no valid lane line; reusing D_LD={d_ld:.3f}")
        else:
            self.faults.clear()
        self.d_msf, self.d_ld = d_msf, d_ld
        return d_msf, d_ld
