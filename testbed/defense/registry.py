"""The defense registry: built-in defenses and the `ld3.defenses` entry points.

A defense component declares its parameter model (`params`, a `testbed.params.Params`: the keys of its
`[defense]` table) and its factory is `factory(params, bicycle: BicycleCoefficients | None)`, given an instance of
that model and returning a `Defense`; `bicycle` carries the vehicle's wheelbase for model-based defenses and the
lever of its reference point for LD3's odometry. Defenses that share a model (LD3 and LD3-NaiveAR share
`DefenseConfig`) name the keys of it they act on in `reads`. A `[defense]` key the defense does not declare (and
the loop does not read: `ALWAYS_READ`) is refused in one line.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from testbed.defense.base import Defense
from testbed.defense.bicycle import BicycleCoefficients
from testbed.defense.config import ALWAYS_READ, DefenseConfig, inert_keys
from testbed.defense.ld3 import Ld3Defense
from testbed.defense.naive_ar import NaiveArDefense
from testbed.defense.no_defense import NoDefense
from testbed.defense.savior import SaviorConfig, SaviorDefense
from testbed.params import Params, ParamsError
from testbed.registry import Capability, Component, Registry

_DETECTION = frozenset({"b", "tau", "existence_threshold", "ld_lines", "fail_closed", "heading_b", "heading_tau",
                        "steer_yaw_tol", "steer_slew", "along_b", "along_tau", "along_gain",
                        "line_rate", "line_yaw_rate",
                        "yaw_margin", "odometry_bias_span", "corner_radius", "lines_gate", "lines_heading_gate",
                        "lines_heading_gate_in_place"})
_LD3 = _DETECTION | {"window", "lam", "p_msf", "p_ld", "r_power", "p_source", "heading", "heading_clamp", "kf_q",
                     "kf_p0", "ar_decel", "response_gate"}


def _lever(bicycle: BicycleCoefficients | None) -> float:
    return (bicycle or BicycleCoefficients()).lever


DEFENSES: Registry[Component] = Registry("defense", Component, "ld3.defenses")
DEFENSES.add(Component("ld3", lambda config, bicycle: Ld3Defense(config, _lever(bicycle)),
                       "LD3: CUSUM on MSF/LD deviation, in-lane stop on the safety-driven fusion",
                       needs=frozenset({Capability.LANE_DETECTOR}), params=DefenseConfig, reads=_LD3))
DEFENSES.add(Component("ld3-naive-ar", lambda config, bicycle: NaiveArDefense(config, _lever(bicycle)),
                       "LD3's detection, a maximum-deceleration stop steered on the MSF",
                       needs=frozenset({Capability.LANE_DETECTOR}), params=DefenseConfig,
                       reads=_DETECTION | {"max_decel"}))
DEFENSES.add(Component("savior", lambda config, bicycle: SaviorDefense(config, bicycle),
                       "SAVIOR: bicycle-model EKF and CUSUM on the GNSS residuals",
                       needs=frozenset({Capability.LANE_DETECTOR, Capability.GNSS}), params=SaviorConfig))
DEFENSES.add(Component("none", lambda config, bicycle: NoDefense(), "no defense: the car steers on the MSF"))


def defense_keys(component: Component) -> frozenset[str]:
    """The `[defense]` keys `component` acts on: those of its model it `reads`, else all of its model's."""
    return component.reads or frozenset(component.params.model_fields)


def defense_settings(name: str, table: Mapping[str, Any]) -> tuple[DefenseConfig, Params]:
    """From a `[defense]` table: the loop's `DefenseConfig` (the keys of it the table sets; the loop reads
    `existence_threshold`, an attacker's white box the LD3 parameters) and defense `name`'s own parameters
    (UnknownComponent for an unknown name). A key the defense does not declare, or a bad value, is a one-line
    ParamsError."""
    component = DEFENSES.get(name)
    keys = defense_keys(component)
    unread = sorted(set(table) - keys - ALWAYS_READ)
    if unread:
        reads = f" (it reads {', '.join(sorted(keys))})" if keys else " (it reads no [defense] keys)"
        raise ParamsError(f"[defense] {', '.join(unread)}: not read by defense {name!r}, so it would change "
                          f"nothing; remove it{reads}")
    loop = DefenseConfig.from_dict({k: v for k, v in table.items() if k in DefenseConfig.model_fields})
    if component.params is DefenseConfig:
        return loop, loop
    return loop, component.settings({k: v for k, v in table.items() if k in component.params.model_fields},
                                    "defense")


def declared_table(name: str, table: Mapping[str, Any]) -> dict[str, Any]:
    """The keys of a recorded `[defense]` table (summary.json's `defense_params`, which holds every built-in
    defense's, each at its default where the run did not set it) that defense `name` declares or the loop reads,
    less those the table's own values make inert (`inert_keys`: a paper-mode run records `heading_clamp` and the
    fail-closed keys at their defaults, which its settings would refuse as set)."""
    keys = (defense_keys(DEFENSES.get(name)) | ALWAYS_READ) - inert_keys(table)
    return {k: v for k, v in table.items() if k in keys}


def explicit_table(name: str, table: Mapping[str, Any]) -> dict[str, Any]:
    """Defense `name`'s parameters from `table` written out in full, defaults included, as a scenario file keeps
    them (so that it keeps its meaning when a default changes): `DefenseConfig.explicit` for the models that
    have it."""
    _, own = defense_settings(name, table)
    keys = defense_keys(DEFENSES.get(name))
    if isinstance(own, DefenseConfig):
        return own.explicit(keys)
    return {k: v for k, v in own.model_dump().items() if k in keys}


def resolved_table(loop: DefenseConfig, own: Params) -> dict[str, Any]:
    """The `[defense]` table as summary.json records it: every built-in defense's parameters at their defaults,
    then the loop's and the run's defense's own values over them."""
    table: dict[str, Any] = {}
    for component in DEFENSES.builtins():
        table.update(component.params().model_dump())
    return {**table, **loop.model_dump(), **own.model_dump()}


def make_defense(name: str, config: Params | None = None, *,
                 bicycle: BicycleCoefficients | None = None) -> Defense:
    """A fresh defense of the registered component `name` with `config` (default: its model's defaults);
    UnknownComponent for an unknown name."""
    component = DEFENSES.get(name)
    return component.factory(config if config is not None else component.params(), bicycle)
