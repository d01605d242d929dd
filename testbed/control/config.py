"""The scenario's `[control]`: the lateral controller's design choices, one typed model."""

from __future__ import annotations

from pydantic import Field

from testbed.params import Params


class ControlConfig(Params):
    """`steer_rate_weight` w > 0 adds w·δ̇² to the lateral LQR's cost (see `LqrLateralController`; the default
    0.03 keeps the 40 Hz loop from ringing, docs/decisions.md); 0 is the plain design, the steering applied at
    once with no cost on its steps. `lateral_accel` bounds the planner's speed in curves (`LanePlanner`: the
    scenario's speed is the cruise speed, the car slows for the curvature ahead so that v²·|κ| stays within it)."""

    steer_rate_weight: float = Field(0.03, ge=0, le=100, description="weight on the steering rate (rad/s)² in the "
                                     "lateral LQR's cost, against 25 on the steering angle (rad)² (s²; the same "
                                     "at any control rate); 0 = no rate cost")
    lateral_accel: float = Field(3.0, gt=0, le=10, description="the planner's lateral-acceleration bound in curves "
                                 "(m/s²): it slows for the curvature ahead so that v²·|κ| stays within it")

    steer_lat_accel: float = Field(10.0, gt=0, description="largest lateral acceleration a steering command may ask "
                                   "for beyond the road's own curvature (m/s²): about a dry road's grip, so a step in "
                                   "the pose cannot command the car into a skid")
