"""Planner (lane follow, in-lane stop) and lateral/longitudinal controllers. No PyBullet, no torch."""
