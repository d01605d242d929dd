"""LD3 detection and response, the NaiveAR and SAVIOR baselines. No PyBullet, no torch."""

from testbed.defense.attack_detection import Cusum, Ld3Detector, cusum_alarm_index
from testbed.defense.base import Defense, DefenseStatus
from testbed.defense.bicycle import BicycleCoefficients, fit_bicycle_coefficients
from testbed.defense.config import DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.naive_ar import NaiveArDefense
from testbed.defense.no_defense import NoDefense
from testbed.defense.registry import DEFENSES, make_defense
from testbed.defense.savior import SaviorDefense

__all__ = [
    "DEFENSES",
    "BicycleCoefficients",
    "Cusum",
    "Defense",
    "DefenseConfig",
    "DefenseStatus",
    "Ld3Defense",
    "Ld3Detector",
    "NaiveArDefense",
    "NoDefense",
    "SaviorDefense",
    "cusum_alarm_index",
    "fit_bicycle_coefficients",
    "make_defense",
]
