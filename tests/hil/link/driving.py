"""A small closed-loop driver for the CAN link tests: lane keeping at 4 m/s on a kinematic plant."""

import math

from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.odometry import KinematicOdometry
from testbed.chassis import ChassisCommand
from tests.hil.conftest import SampleAndHoldPort
from tracks.pose import Pose

START = Pose(0.0, 0.8, 0.05)


def lane_keeper(state):
    """Speed to 4 m/s and hold y = 0, with a gentle weave so the steering keeps moving."""
    pose = state.true_pose
    steer = -0.3 * pose.y - 0.8 * math.remainder(pose.yaw, math.tau) + 0.01 * math.sin(0.7 * state.t)
    return ChassisCommand(max(min(steer, 0.4), -0.4), max(min(1.5 * (4.0 - state.speed), 3.0), -4.0))


def run(port, ticks):
    poses = []
    for _ in range(ticks):
        state = port.read()
        poses.append(state.true_pose)
        port.send(lane_keeper(state))
        port.advance(0.01)
    return poses


def direct_run(ticks):
    return run(SampleAndHoldPort(KinematicBicyclePlant(pose=START)), ticks)


def start_plant() -> KinematicBicyclePlant:
    """Plant factory for the ECU subprocess (`--plant tests.hil.link.driving:start_plant`)."""
    return KinematicBicyclePlant(pose=START)


def start_odometry() -> KinematicOdometry:
    """The bridge's odometry for a plant built by `start_plant` (same start pose and wheelbase)."""
    return KinematicOdometry(START)
