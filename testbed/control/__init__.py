"""Planner (lane follow, in-lane stop) and lateral/longitudinal controllers. No PyBullet, no torch."""

from testbed.control.lateral import LqrLateralController
from testbed.control.lateral_model import LateralModel
from testbed.control.longitudinal import SpeedController
from testbed.control.plan import Plan
from testbed.control.planner import AR_DECEL, LanePlanner

__all__ = ["AR_DECEL", "LanePlanner", "LateralModel", "LqrLateralController", "Plan", "SpeedController"]
