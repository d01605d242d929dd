"""Dead reckoning of the vehicle pose from chassis odometry (wheel speed v, yaw rate ω).

Rigid-body model: between two odometry samples the rear axle moves on the arc of constant speed and yaw rate,
v and ω the means of the two samples' values, and the pose's reference point `lever` ahead of it follows (its
body velocity (v, lever·ω), the kinematic sideslip the MSF models too: 1 m/s sideways at 5 m/s on a radius of
7 m for the sedan's 1.4 m, where a unicycle at the reference point drifts out of the lane in a second).
The pose exists once anchored (`anchor`); samples before that only set the clock. An anchor may correct the yaw
only partly (a complementary filter: the gyro between anchors, the anchor's heading averaged over several). A
sample with a non-finite value or a time that does not advance is refused (the pose holds) and reported to the
caller.

A chassis whose yaw rate is derived from its steering angle (ψ̇ = v tan δ / L) reads a steering-angle offset as a
yaw-rate error proportional to speed; `CurvatureBias` estimates it per metre travelled so the carried yaw does
not drift away from a heading the other sources agree on.
"""

from __future__ import annotations

import math

from tracks.pose import Pose, wrap_angle


def advance(pose: Pose, dt: float, speed: float, yaw_rate: float, lever: float = 0.0) -> Pose:
    """`pose` (of a reference point `lever` m ahead of the rear axle) moved for `dt` s, the rear axle along the
    arc of constant `speed` (m/s) and `yaw_rate` (rad/s)."""
    turn = yaw_rate * dt
    yaw = pose.yaw + turn
    lx = lever * (math.cos(yaw) - math.cos(pose.yaw))
    ly = lever * (math.sin(yaw) - math.sin(pose.yaw))
    if abs(turn) < 1e-9:
        dist = speed * dt
        heading = pose.yaw + 0.5 * turn
        return Pose(pose.x + dist * math.cos(heading) + lx, pose.y + dist * math.sin(heading) + ly, wrap_angle(yaw))
    radius = speed / yaw_rate
    return Pose(pose.x + radius * (math.sin(yaw) - math.sin(pose.yaw)) + lx,
                pose.y - radius * (math.cos(yaw) - math.cos(pose.yaw)) + ly, wrap_angle(yaw))


def drift_allowance(rate: float, elapsed: float) -> float:
    """How far one source alone may move an odometry-carried reference in `elapsed` s at `rate` (per s): without
    limit for an infinite rate, nothing when no time has passed or the rate is 0 (never NaN)."""
    if math.isinf(rate):
        return math.inf
    return rate * elapsed if elapsed > 0.0 and rate > 0.0 else 0.0


def into_span(value: float, a: float, b: float, margin: float = 0.0) -> float:
    """`value` moved into [min(a, b) − margin, max(a, b) + margin], the span of two sources' readings: against one
    attacked source the car reads as the other does, so the move never takes `value` away from the car."""
    return min(max(value, min(a, b) - margin), max(a, b) + margin)


def into_heading_span(own: float, a: float, b: float, max_margin: float) -> float:
    """`own` moved into the span of two sources' headings and the lane's own (rad, relative to the lane, so the lane's
    is 0) widened by the sources' disagreement up to `max_margin`: where they agree nothing widens it; where they
    disagree, the honest one's wandering heading cannot ratchet `own` towards the other's; and where both head to the
    same side of the lane (an honest source's slow heading error beside an attacker's) they turn `own` no farther
    than along the lane, which a car keeping its lane heads along on average."""
    return into_span(own, min(a, b, 0.0), max(a, b, 0.0), min(max_margin, abs(a - b)))


def step_toward(d_from: float, d_to: float, max_step: float) -> float:
    """`d_to`, or the value `max_step` from `d_from` towards it: one source alone moves a reference no faster than
    odometry could drift, so an attacker of that source cannot drag it."""
    return d_from + max(-max_step, min(max_step, d_to - d_from))


class DeadReckoning:
    """A pose carried by odometry from its last anchor; `lever` is its reference point ahead of the rear axle (m)."""

    def __init__(self, lever: float = 0.0) -> None:
        self.lever = lever
        self.pose: Pose | None = None
        self.samples = 0
        """Odometry samples accepted so far (0: the pose, if anchored, has never moved)."""
        self._last: tuple[float, float, float] | None = None  # (t, speed, yaw rate) of the last sample

    def on_odometry(self, t: float, speed: float, yaw_rate: float) -> bool:
        """Advance the pose to time `t`; False (the pose holds) for a sample that is not finite or not later."""
        if not (math.isfinite(t) and math.isfinite(speed) and math.isfinite(yaw_rate)):
            return False
        last = self._last
        if last is not None and t <= last[0]:
            return False
        self._last = (t, speed, yaw_rate)
        self.samples += 1
        if last is None or self.pose is None:
            return True
        self.pose = advance(self.pose, t - last[0], 0.5 * (last[1] + speed), 0.5 * (last[2] + yaw_rate),
                            self.lever)
        return True

    def turn(self, angle: float) -> None:
        """Turn the carried yaw by `angle` (rad), if anchored."""
        if angle and self.pose is not None:
            self.pose = Pose(self.pose.x, self.pose.y, wrap_angle(self.pose.yaw + angle))

    def anchor(self, pose: Pose, yaw_gain: float = 1.0) -> None:
        """Set the position (at the time of the last sample) and move the yaw the share `yaw_gain` of the way to
        `pose.yaw` (all of it for the first anchor); odometry carries the pose from there."""
        if self.pose is None or yaw_gain >= 1.0:
            self.pose = pose
            return
        yaw = wrap_angle(self.pose.yaw + yaw_gain * wrap_angle(pose.yaw - self.pose.yaw))
        self.pose = Pose(pose.x, pose.y, yaw)


MIN_LEVERAGE = 100.0
"""Σ w (s − s̄)² of the samples' odometer readings (m²) before a curvature bias is applied: the slope's standard
error is then 1e-3 rad/m or less for 0.01 rad of independent heading noise a sample (about 6 m of road at 4 m/s
and 20 Hz, 12 m at 27 m/s)."""
MAX_CURVATURE = 0.02
"""Largest curvature bias applied (rad/m): a steering-angle offset of about 3° on a 2.8-m wheelbase."""


class CurvatureBias:
    """Odometry's yaw-rate error per metre travelled κ (rad/m), from headings observed independently of odometry:
    the gap g(s) = heading − ∫ω (the yaw rate as reported) over the odometer s is −κ s + const, so κ is minus its
    slope, fitted by least squares with weights decaying over `span` m of travel. The corrected yaw rate is
    ω − κ v less `deadband` (rad/s) in size: a bias the anchors' turn of the yaw takes out anyway is left to them,
    so the estimate's own noise, amplified by speed, never turns the yaw. No estimate (κ = 0) for a `span` of 0,
    before the samples spread `MIN_LEVERAGE`; never beyond `MAX_CURVATURE`. The first estimate also owes the yaw
    carried since the first observation the turn its bias gave it (`observe` returns it once)."""

    def __init__(self, span: float, deadband: float = 0.0) -> None:
        self.span = span
        self.deadband = deadband
        self.curvature = 0.0
        self.estimated = False
        """Whether the samples have spread `MIN_LEVERAGE` once (the curvature is an estimate from then on)."""
        self._yaw = 0.0  # ∫ω as reported (rad)
        self._odometer = 0.0  # ∫v (m)
        self._last: tuple[float, float, float] | None = None  # (t, speed, yaw rate) of the last sample
        self._origin: tuple[float, float] | None = None  # (odometer, gap) of the last observation: the sums' origin
        self._first = 0.0  # the odometer at the first observation
        self._w = self._sx = self._sxx = self._sg = self._sxg = 0.0

    def correction(self, speed: float) -> float:
        """The yaw-rate error taken out at `speed` (rad/s): κ v, less the deadband in size."""
        bias = self.curvature * speed
        return math.copysign(abs(bias) - self.deadband, bias) if abs(bias) > self.deadband else 0.0

    def corrected(self, speed: float, yaw_rate: float) -> float:
        """The yaw rate with the estimated bias taken out (rad/s)."""
        return yaw_rate - self.correction(speed)

    def on_odometry(self, t: float, speed: float, yaw_rate: float) -> None:
        """Integrate one accepted odometry sample (the yaw rate as reported, uncorrected)."""
        last = self._last
        self._last = (t, speed, yaw_rate)
        if last is not None:
            dt = t - last[0]
            self._odometer += 0.5 * (last[1] + speed) * dt
            self._yaw += 0.5 * (last[2] + yaw_rate) * dt

    def observe(self, heading: float) -> float:
        """One independent heading (rad, world frame) at the present odometer reading; updates `curvature`. Returns
        the turn owed to a yaw carried on the uncorrected rate since the first observation (rad): −κ times the
        distance since then when this is the first estimate, else 0."""
        if self.span <= 0.0 or self._last is None:
            return 0.0
        gap = heading - self._yaw
        if self._origin is None:
            self._origin = (self._odometer, gap)
            self._first = self._odometer
        s0, g0 = self._origin
        gap = g0 + math.remainder(gap - g0, math.tau)
        dx, dg = self._odometer - s0, gap - g0
        f = math.exp(-dx / self.span)
        w, sx, sg = self._w, self._sx, self._sg
        self._w = f * w + 1.0
        self._sx = f * (sx - dx * w)
        self._sxx = f * (self._sxx - 2.0 * dx * sx + dx * dx * w)
        self._sg = f * (sg - dg * w)
        self._sxg = f * (self._sxg - dx * sg - dg * sx + dx * dg * w)
        self._origin = (self._odometer, gap)
        leverage = self._sxx - self._sx * self._sx / self._w
        if leverage < MIN_LEVERAGE:
            return 0.0
        slope = (self._sxg - self._sx * self._sg / self._w) / leverage
        self.curvature = max(-MAX_CURVATURE, min(MAX_CURVATURE, -slope))
        if self.estimated:
            return 0.0
        self.estimated = True
        speed = self._last[1]
        return -self.correction(speed) / speed * (self._odometer - self._first) if speed > 0.0 else 0.0
