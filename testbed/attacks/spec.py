"""Attack specs: the `--attack KIND[:ARGS]` strings of the CLI and the scenario's [attack] table.

Spec grammar: `KIND` or `KIND:ARG,ARG,...`, each ARG `key=value`; a bare first ARG of `trace` is the trace
name or CSV path (`trace:default`, `trace:runs/t.csv,start=5`). Kinds and parameters:
  fusionripper  d f direction(left|right) start trigger obs_std
  trace         trace (name|path) start scale
  stealthy      start margin direction b tau ld_std   (b, tau, ld_std default to the defense's knowledge)
  drp-trace     start shift ramp duration
  drp-bend      start shift bend ramp duration   (bend: rotation of the detected lines, rad, + left)
  drp-patch     at length width offset angle darkness
Every problem raises ValueError with a one-line message.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from testbed.attacks.base import Attack
from testbed.attacks.drp import DrpBend, DrpPatch, DrpTrace
from testbed.attacks.fusionripper import FusionRipper
from testbed.attacks.stealthy import CusumKnowledge, StealthyAttack
from testbed.attacks.trace import Trace, TraceInjection

_STR = {"direction", "trace"}
_PARAMS: dict[str, tuple[str, ...]] = {
    "fusionripper": ("d", "f", "direction", "start", "trigger", "obs_std"),
    "trace": ("trace", "start", "scale"),
    "stealthy": ("start", "margin", "direction", "b", "tau", "ld_std"),
    "drp-trace": ("start", "shift", "ramp", "duration"),
    "drp-bend": ("start", "shift", "bend", "ramp", "duration"),
    "drp-patch": ("at", "length", "width", "offset", "angle", "darkness"),
}
_REQUIRED = {"drp-patch": ("at",)}


def _resolve_trace(ref: str) -> Trace:
    if ref.endswith(".csv") or "/" in ref or "\\" in ref:
        return Trace.load(Path(ref).expanduser())
    return Trace.named(ref)


def _stealthy(p: dict[str, Any], defense: Any) -> StealthyAttack:
    """The stealthy attacker knows the defense's CUSUM b, tau (and LD noise); spec values override."""
    base = CusumKnowledge()
    knowledge = CusumKnowledge(
        b=p.pop("b", getattr(defense, "b", base.b)),
        tau=p.pop("tau", getattr(defense, "tau", base.tau)),
        ld_noise_std=p.pop("ld_std", getattr(defense, "ld_noise_std", base.ld_noise_std)),
    )
    return StealthyAttack(knowledge, **p)


_BUILD: dict[str, Callable[[dict[str, Any], np.random.Generator | None, Any], Attack]] = {
    "fusionripper": lambda p, rng, _: FusionRipper(**p, rng=rng),
    "trace": lambda p, _, __: TraceInjection(_resolve_trace(p.pop("trace", "default")), **p),
    "stealthy": lambda p, _, defense: _stealthy(p, defense),
    "drp-trace": lambda p, _, __: DrpTrace(**p),
    "drp-bend": lambda p, _, __: DrpBend(**p),
    "drp-patch": lambda p, _, __: DrpPatch(**p),
}


def _coerce(kind: str, key: str, value: Any) -> Any:
    if key in _STR:
        if not isinstance(value, str) or not value:
            raise ValueError(f"attack {kind!r}: parameter {key!r} must be a non-empty string, got {value!r}")
        return value
    if isinstance(value, bool):
        raise ValueError(f"attack {kind!r}: parameter {key!r} must be a number, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"attack {kind!r}: parameter {key!r} must be a number, got {value!r}") from None


def build_attack(
    kind: str, params: Mapping[str, Any], rng: np.random.Generator | None = None, defense: Any = None
) -> Attack:
    """Build the attack `kind` from its parameters (validated: unknown, missing, bad values).

    `rng` (the scenario's attack stream) seeds FusionRipper's observation noise; `defense` is anything
    with CUSUM `b` and `tau` attributes (DefenseConfig or CusumKnowledge), what the stealthy attacker knows.
    """
    if kind not in _PARAMS:
        raise ValueError(f"unknown attack kind {kind!r}; known: {', '.join(_PARAMS)}")
    unknown = sorted(set(params) - set(_PARAMS[kind]))
    if unknown:
        raise ValueError(
            f"attack {kind!r}: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(_PARAMS[kind])}"
        )
    missing = [k for k in _REQUIRED.get(kind, ()) if k not in params]
    if missing:
        raise ValueError(f"attack {kind!r}: missing required parameter(s) {', '.join(missing)}")
    p = {k: _coerce(kind, k, v) for k, v in params.items()}
    return _BUILD[kind](p, rng, defense)


def attack_spec_to_dict(spec: str) -> dict[str, Any]:
    """`fusionripper:d=0.5,f=1.3` -> {'kind': 'fusionripper', 'd': 0.5, 'f': 1.3}, an [attack] table."""
    text = spec.strip()
    kind, _, rest = text.partition(":")
    kind = kind.strip()
    if not kind:
        raise ValueError(f"empty attack spec {spec!r}; expected KIND[:key=value,...]")
    if kind not in _PARAMS:
        raise ValueError(f"unknown attack kind {kind!r}; known: {', '.join(_PARAMS)}")
    table: dict[str, Any] = {"kind": kind}
    args = [a.strip() for a in rest.split(",")] if rest.strip() else []
    for i, arg in enumerate(args):
        key, eq, value = arg.partition("=")
        if not eq:
            if kind == "trace" and i == 0 and arg:
                key, value = "trace", arg
            else:
                raise ValueError(f"attack spec {spec!r}: argument {arg!r} is not key=value")
        key, value = key.strip(), value.strip()
        if key == "kind" or key in table:
            raise ValueError(f"attack spec {spec!r}: parameter {key!r} given twice")
        table[key] = value if key in _STR else _number_or_text(value)
    return table


def _number_or_text(value: str) -> float | str:
    try:
        return float(value)
    except ValueError:
        return value


def parse_attack(spec: str, rng: np.random.Generator | None = None, defense: Any = None) -> Attack:
    """Parse a CLI attack spec such as `fusionripper:d=0.5,f=1.3` or `trace:default` (module docstring)."""
    return attack_from_dict(attack_spec_to_dict(spec), rng=rng, defense=defense)


def attack_from_dict(
    table: Mapping[str, Any], rng: np.random.Generator | None = None, defense: Any = None
) -> Attack:
    """Build an attack from a scenario's [attack] table: `kind` plus the parameters of that kind."""
    if not isinstance(table, Mapping) or "kind" not in table:
        raise ValueError(f"attack table needs a 'kind' (one of {', '.join(_PARAMS)}), got {table!r}")
    kind = table["kind"]
    if not isinstance(kind, str):
        raise ValueError(f"attack kind must be a string, got {kind!r}")
    return build_attack(kind, {k: v for k, v in table.items() if k != "kind"}, rng, defense)
