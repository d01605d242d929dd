"""Attack specs: the `--attack KIND[:ARGS]` strings of the CLI and the scenario's [attack] table.

Spec grammar: `KIND` or `KIND:ARG,ARG,...`, each ARG `key=value`; a bare first ARG of `trace` is the trace
name or CSV path (`trace:default`, `trace:runs/t.csv,start=5`). Kinds and their parameters come from the
attack registry (testbed.attacks.registry; `ld3 attacks` lists them). A scenario's `attack` is one table or
a list of them (composed in list order, `testbed.attacks.compose`). Every problem raises ValueError with a
one-line message.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from testbed.attacks.base import Attack
from testbed.attacks.compose import AttackChain
from testbed.attacks.registry import ATTACKS
from testbed.errors import UserError
from testbed.params import Params
from testbed.registry import Component


def attack_settings(table: Mapping[str, Any]) -> tuple[Component, Params]:
    """The attack component a scenario's [attack] table names (`kind`) and its validated parameters
    (UserError for a missing or unknown kind; ParamsError for unknown, missing or bad parameters)."""
    if not isinstance(table, Mapping) or "kind" not in table:
        raise UserError(f"attack table needs a 'kind' (one of {', '.join(ATTACKS.names())}), got {table!r}")
    kind = table["kind"]
    if not isinstance(kind, str):
        raise UserError(f"attack kind must be a string, got {kind!r}")
    component = ATTACKS.get(kind)
    return component, component.settings({k: v for k, v in table.items() if k != "kind"}, f"attack {kind}")


def _value(component: Component, key: str, value: str) -> Any:
    """A spec's value as the parameter's type reads it: text for a text field, a boolean for a `true`/`false` (any
    case, as a search's spec writes them) of a boolean field, else a number where it reads as one."""
    field = component.params.model_fields.get(key)
    if field is not None and field.annotation is str:
        return value
    if field is not None and field.annotation is bool and value.lower() in ("true", "false"):
        return value.lower() == "true"
    return _number_or_text(value)


def attack_spec_to_dict(spec: str) -> dict[str, Any]:
    """`fusionripper:d=0.5,f=1.3` -> {'kind': 'fusionripper', 'd': 0.5, 'f': 1.3}, an [attack] table."""
    text = spec.strip()
    kind, _, rest = text.partition(":")
    kind = kind.strip()
    if not kind:
        raise UserError(f"empty attack spec {spec!r}; expected KIND[:key=value,...]")
    component = ATTACKS.get(kind)
    table: dict[str, Any] = {"kind": kind}
    args = [a.strip() for a in rest.split(",")] if rest.strip() else []
    for i, arg in enumerate(args):
        key, eq, value = arg.partition("=")
        if not eq:
            if kind == "trace" and i == 0 and arg:
                key, value = "trace", arg
            else:
                raise UserError(f"attack spec {spec!r}: argument {arg!r} is not key=value")
        key, value = key.strip(), value.strip()
        if key == "kind" or key in table:
            raise UserError(f"attack spec {spec!r}: parameter {key!r} given twice")
        table[key] = _value(component, key, value)
    return table


def _number_or_text(value: str) -> int | float | str:
    for parse in (int, float):
        try:
            return parse(value)
        except ValueError:
            pass
    return value


def parse_attack(spec: str, rng: np.random.Generator | None = None, defense: Any = None) -> Attack:
    """Parse a CLI attack spec such as `fusionripper:d=0.5,f=1.3` or `trace:default` (module docstring)."""
    return attack_from_dict(attack_spec_to_dict(spec), rng=rng, defense=defense)


def attack_from_dict(
    table: Mapping[str, Any], rng: np.random.Generator | None = None, defense: Any = None
) -> Attack:
    """Build an attack from a scenario's [attack] table: `kind` plus the parameters of that kind.

    `rng` (the scenario's attack stream) seeds FusionRipper's observation noise; `defense` is anything
    with CUSUM `b` and `tau` attributes (DefenseConfig or CusumKnowledge), what the stealthy attacker knows.
    """
    component, settings = attack_settings(table)
    return component.factory(settings.model_dump(exclude_unset=True), rng, defense)


AttackValue = Mapping[str, Any] | list[Mapping[str, Any]] | None
"""A scenario's `attack`: nothing, one [attack] table, or a list of them."""


def attack_tables(value: AttackValue) -> list[Mapping[str, Any]]:
    """The scenario's attack tables as a list (empty without an attack); UserError for any other shape."""
    if value is None:
        return []
    if isinstance(value, Mapping):
        return [value]
    if isinstance(value, list) and value and all(isinstance(t, Mapping) for t in value):
        return list(value)
    raise UserError(f"attack must be a table with a 'kind' or a non-empty list of such tables, got {value!r}")


def build_attack(value: AttackValue, rng: np.random.Generator | None = None, defense: Any = None) -> Attack | None:
    """The run's attack: None, the one attack, or an `AttackChain` of a list's attacks in order."""
    attacks = [attack_from_dict(t, rng=rng, defense=defense) for t in attack_tables(value)]
    if not attacks:
        return None
    return attacks[0] if len(attacks) == 1 else AttackChain(attacks)


def attack_value(tables: list[Mapping[str, Any]]) -> AttackValue:
    """Attack tables as a scenario's `attack` (the inverse of `attack_tables`): None, one table, or the list."""
    return None if not tables else tables[0] if len(tables) == 1 else tables


def specs_to_value(specs: list[str]) -> AttackValue:
    """Repeated `--attack` specs as a scenario's `attack`."""
    return attack_value([attack_spec_to_dict(s) for s in specs])
