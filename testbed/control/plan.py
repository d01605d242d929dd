"""What the planner hands the controllers each tick: path-relative errors and a speed reference."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Plan:
    """Errors of the vehicle reference point w.r.t. the reference path, and the speed profile now.

    lateral_error: m, + = vehicle left of the reference (the lane deviation D).
    heading_error: rad, vehicle yaw − path heading, wrapped to [−π, π).
    curvature: 1/m (+ = turning left) of the reference at the preview point (feed-forward).
    target_speed, target_accel: m/s and m/s² of the speed profile at this instant.
    local_curvature: 1/m of the reference at the projection of the vehicle (reference yaw rate).
    off_map: True when the map could not place the pose and the path terms are held from the last plan.
    """

    lateral_error: float
    heading_error: float
    curvature: float
    target_speed: float
    target_accel: float
    local_curvature: float
    off_map: bool = False
