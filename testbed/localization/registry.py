"""The localization-source registry (built-ins only).

A localization component's factory is `factory(config, rng, lidar_quality, start)`: a zero-argument
callable giving the scenario's `LocalizationConfig` (built only by sources that use it), the run's
localization random stream, the LiDAR feature richness at a world point, and the start pose. It returns
an object with `step(t, chassis_state, spoof_gnss) -> LocalizationEstimate` and `last_gnss`.
"""

from __future__ import annotations

from testbed.localization.stack import GroundTruthLocalization, LocalizationStack
from testbed.registry import Capability, Component, Registry

LOCALIZATIONS: Registry[Component] = Registry("localization", Component)
LOCALIZATIONS.add(Component("truth", lambda config, rng, lidar_quality, start: GroundTruthLocalization(),
                            "the true pose (no sensors, nothing to spoof)"))
LOCALIZATIONS.add(Component(
    "msf", lambda config, rng, lidar_quality, start: LocalizationStack(config(), rng, lidar_quality, start, 0.0),
    "multi-sensor fusion of GNSS, a LiDAR locator and an IMU (error-state EKF)",
    provides=frozenset({Capability.GNSS})))
