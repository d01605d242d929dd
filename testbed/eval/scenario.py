"""Scenarios: TOML files naming the track, vehicle, speed, duration, condition, seed, detector,
localization, attack and defense of one run. A few ship with the package, one per preset.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from testbed.attacks.registry import ATTACKS
from testbed.attacks.spec import AttackValue, attack_settings, attack_spec_to_dict, attack_tables, attack_value
from testbed.defense.config import DefenseConfig
from testbed.defense.registry import DEFENSES
from testbed.errors import UserError
from testbed.localization.registry import LOCALIZATIONS
from testbed.perception.registry import DETECTORS
from testbed.presets import TRACKS, VEHICLES
from testbed.registry import FIXES, Capability, UnknownComponent, missing_needs
from tracks.presets import parse_track_spec


class ScenarioError(UserError):
    """A scenario that cannot be loaded or run; the message is one line for the user."""


@dataclass(frozen=True)
class Scenario:
    name: str
    track: str
    vehicle: str = "sedan"
    speed: float = 12.0
    duration: float = 60.0
    condition: str = "day"
    seed: int = 0
    lane: int | None = None
    start_s: float = 20.0
    detector: str = "oracle"
    detector_params: dict[str, Any] = field(default_factory=dict)
    localization: str = "truth"
    defense: str = "none"
    defense_params: dict[str, Any] = field(default_factory=dict)
    attack: AttackValue = None
    """One [attack] table, a list of them (composed in order), or None."""
    rates: dict[str, float] = field(default_factory=dict)
    stop_at: float | None = None
    """A planned in-lane stop at this time (s) and `stop_decel`, independent of any defense."""
    stop_decel: float = 4.0

    def with_overrides(self, **overrides: Any) -> Scenario:
        """A copy with the given non-None fields replaced, validated."""
        changes = {k: v for k, v in overrides.items() if v is not None}
        return validate(dataclasses.replace(self, **changes))


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ScenarioError(msg)


ALWAYS_READ = frozenset({"existence_threshold"})
"""`[defense]` keys the loop itself reads (the logged D_LD), whatever the defense."""


def validate(sc: Scenario) -> Scenario:
    """`sc` when its values, component names and every component's parameters are valid; else ScenarioError."""
    _check(sc.speed > 0, f"speed must be > 0 m/s, got {sc.speed}")
    _check(sc.duration > 0, f"duration must be > 0 s, got {sc.duration}")
    _check(sc.seed >= 0, f"seed must be >= 0, got {sc.seed}")
    try:
        track, _ = parse_track_spec(sc.track)
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    for registry, name in ((TRACKS, track), (VEHICLES, sc.vehicle), (LOCALIZATIONS, sc.localization),
                           (DETECTORS, sc.detector), (DEFENSES, sc.defense)):
        _check(isinstance(name, str) and name in registry,
               f"unknown {registry.family} {name!r}; known: {', '.join(registry.names())}")
    defense = DEFENSES.get(sc.defense)
    unread = sorted(set(sc.defense_params) - defense.reads - ALWAYS_READ)
    _check(not unread, f"[defense] {', '.join(unread)}: not read by defense {sc.defense!r}, so it would change "
                       f"nothing; remove it" + (f" (it reads {', '.join(sorted(defense.reads))})" if defense.reads
                                                else " (it reads no [defense] keys)"))
    try:
        DefenseConfig.from_dict(sc.defense_params)
        DETECTORS.get(sc.detector).settings(sc.detector_params, f"detector {sc.detector}")
        for table in attack_tables(sc.attack):
            attack_settings(table)
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    return sc


def check_needs(sc: Scenario) -> frozenset[Capability]:
    """What the scenario's detector and localization provide; ScenarioError, naming the fix, when its defense
    or attack could not act with them (each component declares its needs in its registry)."""
    provided = DETECTORS.get(sc.detector).provides | LOCALIZATIONS.get(sc.localization).provides
    users = [("defense", DEFENSES.get(sc.defense))]
    try:
        users += [("attack", ATTACKS.get(str(t.get("kind")))) for t in attack_tables(sc.attack)]
    except UnknownComponent as exc:
        raise ScenarioError(str(exc)) from None
    for family, component in users:
        missing = missing_needs(component, provided)
        _check(not missing, f"{family} {component.name!r} has no effect with detector = {sc.detector!r} and "
                            f"localization = {sc.localization!r}: it needs {FIXES[missing[0]] if missing else ''}")
    return provided


_TOP_KEYS = {f.name for f in dataclasses.fields(Scenario)} - {"defense_params", "detector_params"}


def _kind_and_params(value: Any, default_kind: str) -> tuple[Any, dict[str, Any]]:
    """A component key given as a name, or as a table with `kind` and that component's parameters."""
    if isinstance(value, dict):
        params = dict(value)
        return params.pop("kind", default_kind), params
    return value, {}


def scenario_from_dict(data: dict[str, Any], name: str) -> Scenario:
    """Build a scenario from a parsed TOML document; `[defense]` and `[detector]` may be tables with `kind`
    and parameters."""
    data = dict(data)
    defense, params = _kind_and_params(data.pop("defense", "none"), "ld3")
    detector, detector_params = _kind_and_params(data.pop("detector", "oracle"), "oracle")
    unknown = set(data) - _TOP_KEYS
    _check(not unknown, f"scenario {name}: unknown keys {sorted(unknown)}")
    _check("track" in data, f"scenario {name}: 'track' is required")
    data.setdefault("name", name)
    try:
        sc = Scenario(defense=defense, defense_params=params, detector=detector, detector_params=detector_params,
                      **data)
    except TypeError as exc:
        raise ScenarioError(f"scenario {name}: {exc}") from None
    for key, typ in (("speed", (int, float)), ("duration", (int, float)), ("seed", int), ("track", str)):
        _check(isinstance(getattr(sc, key), typ), f"scenario {name}: {key} has the wrong type")
    return validate(sc)


def _toml_value(raw: str) -> Any:
    """A `--set` value as TOML reads it (numbers, booleans, quoted strings); anything else as a bare string."""
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        return raw


def apply_settings(sc: Scenario, settings: list[str]) -> Scenario:
    """`KEY=VALUE` overrides as the TOML would give them: `defense.b=0.45` (the [defense] table, `kind` its
    name), `detector.weights=path.pt` (the [detector] table), `attack.start=12` (the [attack] table), or a
    top-level key such as `speed=10`."""
    top: dict[str, Any] = {}
    defense, params = sc.defense, dict(sc.defense_params)
    detector, detector_params = sc.detector, dict(sc.detector_params)
    attacks = [dict(t) for t in attack_tables(sc.attack)]
    for item in settings:
        key, eq, raw = item.partition("=")
        key = key.strip()
        _check(bool(eq) and bool(key), f"--set {item!r}: expected KEY=VALUE, e.g. defense.b=0.45")
        value = _toml_value(raw.strip())
        section, dot, name = key.partition(".")
        if not dot:
            plain = sorted(_TOP_KEYS - {"defense", "attack", "detector"})
            _check(key in plain, f"--set {item!r}: unknown scenario key {key!r}; known: {plain}")
            top[key] = value
        elif section == "defense":
            if name == "kind":
                defense = value
            else:
                params[name] = value
        elif section == "detector":
            if name == "kind":
                detector = value
            else:
                detector_params[name] = value
        elif section == "attack":
            _check(bool(attacks), f"--set {item!r}: the scenario has no attack; add one with --attack KIND")
            index, dot, member_key = name.partition(".")
            if len(attacks) > 1 or (dot and index.isdigit()):
                _check(bool(dot) and index.isdigit() and int(index) < len(attacks),
                       f"--set {item!r}: the scenario composes {len(attacks)} attacks; name one as "
                       f"attack.N.KEY with N in 0..{len(attacks) - 1}")
                attacks[int(index)][member_key] = value
            else:
                attacks[0][name] = value
        else:
            raise ScenarioError(f"--set {item!r}: unknown section {section!r}; use defense.KEY, detector.KEY, "
                                f"attack.KEY or KEY")
    try:
        changed = dataclasses.replace(sc, defense=defense, defense_params=params, detector=detector,
                                      detector_params=detector_params, attack=attack_value(attacks), **top)
    except TypeError as exc:
        raise ScenarioError(f"--set: {exc}") from None
    return validate(changed)


def add_attacks(sc: Scenario, specs: list[str]) -> Scenario:
    """`sc` with the `--attack` specs composed after its own attacks (hooks run in that order)."""
    if not specs:
        return sc
    tables = [*attack_tables(sc.attack), *(attack_spec_to_dict(spec) for spec in specs)]
    return validate(dataclasses.replace(sc, attack=attack_value(tables)))


def shipped_scenarios() -> list[str]:
    root = resources.files("testbed.eval") / "scenarios"
    return sorted(p.name.removesuffix(".toml") for p in root.iterdir() if p.name.endswith(".toml"))


def load_scenario(name_or_path: str) -> Scenario:
    """A shipped scenario by name, or a TOML file by path."""
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        _check(path.is_file(), f"scenario file not found: {path}")
        text, name = path.read_text(), path.stem
    else:
        res = resources.files("testbed.eval") / "scenarios" / f"{name_or_path}.toml"
        _check(res.is_file(),
               f"unknown scenario {name_or_path!r}; shipped: {', '.join(shipped_scenarios())} (or a .toml path)")
        text, name = res.read_text(), name_or_path
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"malformed TOML in {name_or_path}: {exc}") from None
    return scenario_from_dict(data, name)
