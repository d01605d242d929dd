"""Dead reckoning of the vehicle pose from chassis odometry (wheel speed v, yaw rate ω).

Rigid-body model: between two odometry samples the rear axle moves on the arc of constant speed and yaw rate,
v and ω the means of the two samples' values, and the pose's reference point `lever` ahead of it follows (its
body velocity (v, lever·ω), the kinematic sideslip the MSF models too: 1 m/s sideways at 5 m/s on a radius of
7 m for the sedan's 1.4 m, where a unicycle at the reference point drifts out of the lane in a second).
The pose exists once anchored (`anchor`); samples before that only set the clock. An anchor may correct the yaw
only partly (a complementary filter: the gyro between anchors, the anchor's heading averaged over several). A
sample with a non-finite value or a time that does not advance is refused (the pose holds) and reported to the
caller.
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

    def anchor(self, pose: Pose, yaw_gain: float = 1.0) -> None:
        """Set the position (at the time of the last sample) and move the yaw the share `yaw_gain` of the way to
        `pose.yaw` (all of it for the first anchor); odometry carries the pose from there."""
        if self.pose is None or yaw_gain >= 1.0:
            self.pose = pose
            return
        yaw = wrap_angle(self.pose.yaw + yaw_gain * wrap_angle(pose.yaw - self.pose.yaw))
        self.pose = Pose(pose.x, pose.y, yaw)
