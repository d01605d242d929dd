"""The defense registry: built-in defenses and the `ld3.defenses` entry points.

A defense component's factory is `factory(config: DefenseConfig, bicycle: BicycleCoefficients | None)`,
returning a `Defense`; `bicycle` carries the vehicle's wheelbase for model-based defenses and the lever of its
reference point for LD3's odometry. `reads` names
the `[defense]` keys the defense uses; a scenario that sets any other is refused.
"""

from __future__ import annotations

from testbed.defense.base import Defense
from testbed.defense.bicycle import BicycleCoefficients
from testbed.defense.config import DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.naive_ar import NaiveArDefense
from testbed.defense.no_defense import NoDefense
from testbed.defense.savior import SaviorDefense
from testbed.registry import Capability, Component, Registry

_DETECTION = frozenset({"b", "tau", "existence_threshold", "fail_closed", "heading_b", "heading_tau",
                        "steer_yaw_tol", "along_b", "along_tau", "along_gain", "corner_radius"})
_LD3 = _DETECTION | {"window", "lam", "p_msf", "p_ld", "r_power", "p_source", "heading", "heading_clamp", "kf_q",
                     "kf_p0", "ar_decel", "response_gate"}
_SAVIOR = frozenset({"savior_b", "savior_tau", "savior_speed_std", "savior_accel_std", "savior_yaw_rate_std",
                     "ar_decel"})



def _lever(bicycle: BicycleCoefficients | None) -> float:
    return (bicycle or BicycleCoefficients()).lever


DEFENSES: Registry[Component] = Registry("defense", Component, "ld3.defenses")
DEFENSES.add(Component("ld3", lambda config, bicycle: Ld3Defense(config, _lever(bicycle)),
                       "LD3: CUSUM on MSF/LD deviation, in-lane stop on the safety-driven fusion",
                       needs=frozenset({Capability.LANE_DETECTOR}), reads=_LD3))
DEFENSES.add(Component("ld3-naive-ar", lambda config, bicycle: NaiveArDefense(config, _lever(bicycle)),
                       "LD3's detection, a maximum-deceleration stop steered on the MSF",
                       needs=frozenset({Capability.LANE_DETECTOR}), reads=_DETECTION | {"max_decel"}))
DEFENSES.add(Component("savior", lambda config, bicycle: SaviorDefense(config, bicycle),
                       "SAVIOR: bicycle-model EKF and CUSUM on the GNSS residuals",
                       needs=frozenset({Capability.LANE_DETECTOR, Capability.GNSS}), reads=_SAVIOR))
DEFENSES.add(Component("none", lambda config, bicycle: NoDefense(), "no defense: the car steers on the MSF"))


def make_defense(name: str, config: DefenseConfig | None = None, *,
                 bicycle: BicycleCoefficients | None = None) -> Defense:
    """A fresh defense of the registered component `name` (UnknownComponent for an unknown name)."""
    return DEFENSES.get(name).factory(config or DefenseConfig(), bicycle)
