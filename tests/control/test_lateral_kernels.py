"""The compiled lateral law commands to the bit as the pure-Python `LqrLateralController.update` does: random
plans and speeds across the schedule (standing, below it, beyond it), with and without the gyro's yaw rate,
with the steering-rate cost and without, with and without the lateral-acceleration cap, the last command carried
from tick to tick; and on a drive of the planner and controller along a curvy road."""

import math

import numpy as np
import pytest

from testbed.control.lateral import LqrLateralController
from testbed.control.plan import Plan
from testbed.control.planner import LanePlanner
from tests.control.closed_loop import controller_model
from tests.tracks.test_map_kernels import bits
from tracks.compiled import compiled_module
from tracks.presets import load_track
from tracks.semantic_map import TrackMap

KERNELS = compiled_module("testbed.control.lateral_kernels")
compiled = pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")


def pair(**tuning: float) -> tuple[LqrLateralController, LqrLateralController]:
    fast = LqrLateralController(controller_model(), 0.6, 0.025, **tuning)
    slow = LqrLateralController(controller_model(), 0.6, 0.025, **tuning)
    slow._law = None
    assert fast._law is not None
    return fast, slow


@compiled
@pytest.mark.parametrize("tuning", [{}, {"steer_rate_weight": 0.03}, {"steer_rate_weight": 0.03, "max_lat_accel": 3.0},
                                    {"max_lat_accel": 2.0}])
def test_the_compiled_law_commands_as_the_python_one(tuning):
    fast, slow = pair(**tuning)
    rng = np.random.default_rng(7)
    for k in range(4000):
        plan = Plan(float(rng.normal(0.0, 0.5)), float(rng.normal(0.0, 0.3)), float(rng.normal(0.0, 0.02)),
                    10.0, 0.0, float(rng.normal(0.0, 0.02)))
        speed = float(rng.choice([rng.uniform(0.0, 45.0), 0.05, 0.0, 1.0, 40.0, 39.99, 12.5]))
        yaw_rate = None if k % 5 == 0 else float(rng.normal(0.0, 0.3))
        a, b = fast.update(plan, speed, yaw_rate=yaw_rate), slow.update(plan, speed, yaw_rate=yaw_rate)
        assert bits((a, fast._last)) == bits((b, slow._last)), (k, plan, speed, yaw_rate)
        if k % 997 == 0:
            fast.reset()
            slow.reset()


@compiled
def test_a_non_finite_speed_is_refused_as_in_python():
    fast, slow = pair(steer_rate_weight=0.03)
    for ctl in (fast, slow):
        with pytest.raises(ValueError, match="NaN"):
            ctl.update(Plan(0.1, 0.0, 0.0, 10.0, 0.0, 0.0), math.nan)


@compiled
def test_a_drive_commands_as_the_python_one():
    """Planner and controller along urban-curvy, the car moved along the lane by the commands' curvature."""
    track = load_track("urban-curvy@101")
    smap, lane = TrackMap(track), track.ego_lane
    fast, slow = pair(steer_rate_weight=0.03, max_lat_accel=3.0)
    planner = LanePlanner(smap, lane, 12.0)
    pose, speed = track.start_pose(lane, 5.0), 12.0
    rng = np.random.default_rng(2)
    for k in range(1500):
        plan = planner.plan(pose, speed, k * 0.025)
        yaw_rate = float(rng.normal(0.0, 0.05))
        a, b = fast.update(plan, speed, yaw_rate=yaw_rate), slow.update(plan, speed, yaw_rate=yaw_rate)
        assert bits((a,)) == bits((b,)), k
        yaw = pose.yaw + speed * math.tan(a) / 2.7 * 0.025
        pose = type(pose)(pose.x + speed * 0.025 * math.cos(yaw), pose.y + speed * 0.025 * math.sin(yaw), yaw)
