"""Dead reckoning of the vehicle pose from chassis odometry (wheel speed v, yaw rate ω).

Unicycle model: between two odometry samples the reference point moves on the arc of constant speed and yaw
rate, v and ω the means of the two samples' values. The pose exists once anchored (`anchor`); samples before
that only set the clock. An anchor may correct the yaw only partly (a complementary filter: the gyro between
anchors, the anchor's heading averaged over several). A sample with a non-finite value or a time that does not
advance is refused (the pose holds) and reported to the caller.
"""

from __future__ import annotations

import math

from tracks.pose import Pose, wrap_angle


def advance(pose: Pose, dt: float, speed: float, yaw_rate: float) -> Pose:
    """`pose` moved for `dt` s along the arc of constant `speed` (m/s) and `yaw_rate` (rad/s)."""
    turn = yaw_rate * dt
    if abs(turn) < 1e-9:
        dist = speed * dt
        heading = pose.yaw + 0.5 * turn
        return Pose(pose.x + dist * math.cos(heading), pose.y + dist * math.sin(heading), wrap_angle(pose.yaw + turn))
    radius = speed / yaw_rate
    yaw = pose.yaw + turn
    return Pose(pose.x + radius * (math.sin(yaw) - math.sin(pose.yaw)),
                pose.y - radius * (math.cos(yaw) - math.cos(pose.yaw)), wrap_angle(yaw))


class DeadReckoning:
    """A pose carried by odometry from its last anchor."""

    def __init__(self) -> None:
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
        self.pose = advance(self.pose, t - last[0], 0.5 * (last[1] + speed), 0.5 * (last[2] + yaw_rate))
        return True

    def anchor(self, pose: Pose, yaw_gain: float = 1.0) -> None:
        """Set the position (at the time of the last sample) and move the yaw the share `yaw_gain` of the way to
        `pose.yaw` (all of it for the first anchor); odometry carries the pose from there."""
        if self.pose is None or yaw_gain >= 1.0:
            self.pose = pose
            return
        yaw = wrap_angle(self.pose.yaw + yaw_gain * wrap_angle(pose.yaw - self.pose.yaw))
        self.pose = Pose(pose.x, pose.y, yaw)
