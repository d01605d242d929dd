"""A tiny numpy closed loop for localization and attack tests: a kinematic bicycle that steers on the MSF.

Lanes: a straight lane along +x and a left-hand arc of radius R from the origin. The controller is a
Stanley-like law on the (possibly attacked) MSF pose with curvature feed-forward; the steering actuator
is a first-order lag. Everything runs at 100 Hz; the LocalizationStack sees the true state as the
PyBullet loop would give it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from testbed.attacks.base import Attack, AttackerView
from testbed.chassis import ChassisState
from testbed.localization.stack import LocalizationConfig, LocalizationStack
from tracks.pose import Pose

WHEELBASE = 2.8
REF_AHEAD_OF_REAR_AXLE = 1.4


@dataclass(frozen=True)
class Lane:
    """Straight lane along +x (radius None) or a left-turning arc of radius `radius`, from the origin."""

    radius: float | None = None

    def frame(self, x: float, y: float) -> tuple[float, float, float, float]:
        """(s, signed deviation + left, heading, curvature) of a world point."""
        if self.radius is None:
            return x, y, 0.0, 0.0
        r = self.radius
        dx, dy = x, y - r
        ang = math.atan2(dy, dx)
        return r * (ang + math.pi / 2), r - math.hypot(dx, dy), ang + math.pi / 2, 1.0 / r


def banded_quality(
    period: float = 400.0, poor_len: float = 60.0, poor_q: float = 0.4, rich_q: float = 0.85
) -> Callable[[Lane], Callable[[float, float], float]]:
    """Feature quality `rich_q` except for a `poor_len` stretch of `poor_q` every `period` metres of arc."""

    def make(lane: Lane) -> Callable[[float, float], float]:
        def q(x: float, y: float) -> float:
            s = lane.frame(x, y)[0]
            return poor_q if (s % period) > period - poor_len else rich_q

        return q

    return make


@dataclass
class Run:
    t: list[float] = field(default_factory=list)
    phys_dev: list[float] = field(default_factory=list)
    msf_dev: list[float] = field(default_factory=list)
    msf_lat_err: list[float] = field(default_factory=list)
    stage: list[str] = field(default_factory=list)
    offset: list[float] = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v) for k, v in self.__dict__.items()}


def run_closed_loop(
    lane: Lane,
    speed: float,
    duration: float,
    seed: int,
    attack: Attack | None = None,
    quality: Callable[[Lane], Callable[[float, float], float]] | None = None,
    config: LocalizationConfig | None = None,
) -> Run:
    dt = 0.01
    rng = np.random.default_rng(seed)
    quality = quality or banded_quality()
    pose = Pose(0.0, 0.0, 0.0)
    steer = math.atan(WHEELBASE / lane.radius) if lane.radius else 0.0
    stack = LocalizationStack(config or LocalizationConfig(), rng, quality(lane), pose, speed)
    out = Run()
    for i in range(round(duration / dt)):
        t = i * dt
        yaw_rate = speed * math.tan(steer) / WHEELBASE
        state = ChassisState(t=t, speed=speed, steer=steer, accel=0.0, true_pose=pose, yaw_rate=yaw_rate)
        _, phys, heading, _ = lane.frame(pose.x, pose.y)
        view = AttackerView(t, pose, phys, heading, speed)
        spoof = (lambda fix, v=view: attack.spoof_gnss(fix, v)) if attack is not None else None
        est = stack.step(t, state, spoof)
        true_msf_dev = lane.frame(est.pose.x, est.pose.y)[1]
        if attack is not None:
            est = attack.tamper_msf(est, view)
        m = est.pose
        _, e, h, kappa = lane.frame(m.x, m.y)
        e_psi = (m.yaw - h + math.pi) % (2 * math.pi) - math.pi
        target = math.atan(WHEELBASE * kappa) - e_psi - math.atan2(0.6 * e, max(speed, 1.0))
        target = max(-0.5, min(0.5, target))
        steer += (target - steer) * dt / 0.1
        out.t.append(t)
        out.phys_dev.append(phys)
        out.msf_dev.append(e)
        out.msf_lat_err.append(true_msf_dev - phys)
        st = attack.state() if attack is not None else {"stage": "", "offset": 0.0}
        out.stage.append(st["stage"])
        out.offset.append(st["offset"])
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        lat = REF_AHEAD_OF_REAR_AXLE * yaw_rate  # the reference point (footprint centre) side-slips on curves
        pose = Pose(pose.x + (speed * c - lat * s) * dt, pose.y + (speed * s + lat * c) * dt, pose.yaw + yaw_rate * dt)
    return out
