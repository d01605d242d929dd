"""Builds a defense by its scenario name: "ld3", "ld3-naive-ar", "savior" or "none"."""

from __future__ import annotations

from testbed.defense.base import Defense
from testbed.defense.bicycle import BicycleCoefficients
from testbed.defense.config import DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.naive_ar import NaiveArDefense
from testbed.defense.no_defense import NoDefense
from testbed.defense.savior import SaviorDefense

DEFENSE_NAMES = ("ld3", "ld3-naive-ar", "savior", "none")


def make_defense(
    name: str, config: DefenseConfig | None = None, *, bicycle: BicycleCoefficients | None = None
) -> Defense:
    """A fresh defense; `bicycle` are SAVIOR's fitted coefficients (vanilla model when None)."""
    config = config or DefenseConfig()
    if name == "ld3":
        return Ld3Defense(config)
    if name == "ld3-naive-ar":
        return NaiveArDefense(config)
    if name == "savior":
        return SaviorDefense(config, bicycle)
    if name == "none":
        return NoDefense()
    raise ValueError(f"unknown defense {name!r}; expected one of {', '.join(DEFENSE_NAMES)}")
