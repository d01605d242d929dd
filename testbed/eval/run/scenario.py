"""Scenarios: TOML files naming the track, vehicle, speed, duration, condition, seed, detector,
localization, attack and defense of one run. A few ship with the package, one per preset.
"""

from __future__ import annotations

import logging
import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import BaseModel, Field, ValidationError, model_validator

from testbed.attacks.registry import ATTACKS
from testbed.attacks.spec import AttackValue, attack_settings, attack_spec_to_dict, attack_tables, attack_value
from testbed.chassis import ChassisModel
from testbed.control.config import ControlConfig
from testbed.defense.registry import DEFENSES, defense_settings
from testbed.errors import UserError
from testbed.localization.registry import LOCALIZATIONS
from testbed.params import error_key, error_problem
from testbed.perception.detectors.registry import DETECTORS
from testbed.presets import TRACKS, VEHICLES
from testbed.rates import STRICT, Rates
from testbed.registry import FIXES, Capability, UnknownComponent, missing_needs
from testbed.traffic.config import TrafficConfig
from tracks.presets import parse_track_spec


class ScenarioError(UserError):
    """A scenario that cannot be loaded or run; the message is one line for the user."""


END_MARGIN_M = 30.0
"""A run ends this far before the end of its road."""
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.@+=,-]*$"
"""A run name is one safe path component: it names the run's folder under `runs/`."""


class Scenario(BaseModel):
    """One run: track, vehicle, speed, duration, condition, seed, and the detector, localization, defense and
    attack with their parameters. Every value is checked on construction (types, finite, ranges, names in
    their registries, each component's parameters, and cross-field rules); a bad one is a `ScenarioError`."""

    model_config = STRICT

    name: str = Field(pattern=NAME_PATTERN, max_length=120, description="run name (default: the file's stem)")
    track: str = Field(description="track preset, `NAME` or `NAME@SEED` (a seed > 0 draws a held-out variant), "
                                   "or a route of an OpenDRIVE file, `xodr:PATH[#ROAD,ROAD,...]`")
    vehicle: str = Field("sedan", description="vehicle")
    speed: float = Field(12.0, gt=0, le=100, description="target speed (m/s)")
    duration: float = Field(60.0, gt=0, le=86_400, description="simulated duration (s)")
    condition: str = Field("day", description="lighting and weather of the camera (`ld3 scenarios` lists them)")
    seed: int = Field(0, ge=0, lt=2**63, description="seed of every random draw of the run")
    lane: int | None = Field(None, ge=0, description="lane driven, 0 = rightmost (default: the track's ego lane)")
    start_s: float = Field(20.0, ge=0, description="start position along the road (m)")
    detector: str = Field("oracle", description="lane detector: a name, or a [detector] table with `kind` and "
                                                "its parameters")
    detector_params: dict[str, Any] = Field(default_factory=dict)
    localization: str = Field("truth", description="localization source")
    defense: str = Field("none", description="defense: a name, or a [defense] table with `kind` (default ld3) "
                                             "and parameters")
    defense_params: dict[str, Any] = Field(default_factory=dict)
    attack: AttackValue = Field(None, description="an [attack] table with `kind` and its parameters, a list of "
                                                  "them (composed in order), or none")
    rates: Rates = Field(default_factory=Rates, description="[rates]: physics_hz, control_hz, camera_hz, "
                                                            "command_hold_s and a [rates.localization] table")
    stop_at: float | None = Field(None, ge=0, description="time of a planned in-lane stop (s), independent of "
                                                          "any defense")
    stop_decel: float = Field(4.0, gt=0, le=15, description="deceleration of the planned stop (m/s²)")
    traffic: TrafficConfig = Field(default_factory=TrafficConfig, description="[traffic]: same-direction cars "
                                                                              "on IDM, their lanes, gaps and speeds")
    control: ControlConfig = Field(default_factory=ControlConfig, description="[control]: the lateral "
                                                                              "controller's design")
    chassis: ChassisModel = Field(default_factory=ChassisModel, description="[chassis]: what the simulated car's "
                                  "chassis reports: its yaw rate or one derived from its steering, and a "
                                  "steering-sensor offset")

    @model_validator(mode="after")
    def _components(self) -> Scenario:
        from testbed.conditions import get_condition  # the camera's conditions need OpenCV (not on a vehicle)

        track, _ = parse_track_spec(self.track)
        get_condition(self.condition)
        for registry, name in ((TRACKS, track), (VEHICLES, self.vehicle), (LOCALIZATIONS, self.localization),
                               (DETECTORS, self.detector), (DEFENSES, self.defense)):
            _check(name in registry, f"unknown {registry.family} {name!r}; known: {', '.join(registry.names())}")
        defense_settings(self.defense, self.defense_params)
        DETECTORS.get(self.detector).settings(self.detector_params, f"detector {self.detector}")
        for table in attack_tables(self.attack):
            component, settings = attack_settings(table)
            start = getattr(settings, "start", None)
            if start is not None and start >= self.duration:
                raise ScenarioError(f"attack {component.name!r} starts at {start:g} s but the run lasts "
                                    f"{self.duration:g} s, so it would never act: lower attack start or raise duration")
        if self.stop_at is not None and self.stop_at >= self.duration:
            raise ScenarioError(f"stop_at = {self.stop_at:g} s lies after the run's end ({self.duration:g} s): lower "
                                f"it or raise duration")
        return self

    @property
    def run_detector_params(self) -> dict[str, Any]:
        """The `[detector]` parameters the run's detector is built with: as given, with and without traffic (a
        neural detector that names no weights reads the shipped `lanenet.pt` in every run)."""
        return dict(self.detector_params)

    @classmethod
    def build(cls, **fields: Any) -> Scenario:
        """A scenario from its fields, or a one-line ScenarioError naming the first bad one."""
        try:
            return cls.model_validate(fields)
        except ValidationError as exc:
            raise ScenarioError(_one_line(exc)) from None

    def replace(self, **changes: Any) -> Scenario:
        """A validated copy with `changes` applied."""
        return Scenario.build(**{**self.fields(), **changes})

    def with_overrides(self, **overrides: Any) -> Scenario:
        """A validated copy with the given non-None fields replaced."""
        return self.replace(**{k: v for k, v in overrides.items() if v is not None})

    def fields(self) -> dict[str, Any]:
        """The fields as given (`rates` as its model), for a copy."""
        return {name: getattr(self, name) for name in type(self).model_fields}


def _one_line(exc: ValidationError) -> str:
    """The first error of a scenario validation as one line naming its key."""
    err = exc.errors()[0]
    key = error_key(err)
    if err["type"] == "extra_forbidden":
        section = key.rpartition(".")[0]
        known = _SECTIONS[section].model_fields if section in _SECTIONS else _TOP_KEYS
        return f"unknown scenario key {key!r}; known{f' in [{section}]' if section in _SECTIONS else ''}: " \
               f"{', '.join(sorted(known))}"
    if err["loc"][:1] == ("attack",) and err["type"] != "value_error":
        return f"attack must be a table with a 'kind' or a non-empty list of such tables, got {err['input']!r}"
    if not key or err["type"] == "value_error":
        return error_problem(err)
    if err["type"] == "string_pattern_mismatch" and key == "name":
        return (f"name {err['input']!r} must be one path component: letters, digits and _ . @ + = , -, "
                f"not starting with a dot")
    return f"{key} {error_problem(err)}"


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise ScenarioError(msg)


def check_needs(sc: Scenario) -> frozenset[Capability]:
    """What the scenario's detector and localization provide; ScenarioError, naming the fix, when its defense
    or attack could not act with them (each component declares its needs in its registry); a warning for a
    lane-detection attack under a defense that does not read the lines (it changes only the recorded D_LD)."""
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
    reads_lines = Capability.LANE_DETECTOR in DEFENSES.get(sc.defense).needs
    for _, component in users[1:]:
        if not reads_lines and component.capabilities & LD_SIDE:
            logger.warning("attack %r tampers with the lane detection, which defense %r does not read (nothing else "
                           "steers by it): it changes only the recorded D_LD; use a defense that reads the lines, "
                           "e.g. --defense ld3, for it to act on the drive", component.name, sc.defense)
    return provided


logger = logging.getLogger(__name__)
LD_SIDE = frozenset({"ld-output", "road-paint"})
"""Attack capabilities that act on the lane detection (`testbed.attacks.threat.ThreatCapability` values)."""
_TOP_KEYS = set(Scenario.model_fields) - {"defense_params", "detector_params"}
_SECTIONS: dict[str, type[BaseModel]] = {"rates": Rates, "traffic": TrafficConfig, "control": ControlConfig,
                                         "chassis": ChassisModel}
"""The scenario's typed tables, by name."""


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
    _check(not unknown, f"scenario {name}: unknown keys {sorted(unknown)}; known: {', '.join(sorted(_TOP_KEYS))}")
    _check("track" in data, f"scenario {name}: 'track' is required")
    data.setdefault("name", name)
    try:
        return Scenario.build(defense=defense, defense_params=params, detector=detector,
                              detector_params=detector_params, **data)
    except ScenarioError as exc:
        raise ScenarioError(f"scenario {name}: {exc}") from None


def _toml_value(raw: str) -> Any:
    """A `--set` value as TOML reads it (numbers, booleans, quoted strings); anything else as a bare string."""
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except (tomllib.TOMLDecodeError, RecursionError):
        return raw


def apply_settings(sc: Scenario, settings: list[str]) -> Scenario:
    """`KEY=VALUE` overrides as the TOML would give them: `defense.b=0.45` (the [defense] table, `kind` its
    name), `detector.weights=path.pt` (the [detector] table), `attack.start=12` (the [attack] table),
    `rates.control_hz=40` or `rates.localization.gnss_hz=5` (the [rates] table), `traffic.vehicles=6` (the
    [traffic] table), `control.steer_rate_weight=0.1` (the [control] table), `chassis.yaw_rate="steering"` (the
    [chassis] table), or a top-level key such as `speed=10`."""
    top: dict[str, Any] = {}
    defense, params = sc.defense, dict(sc.defense_params)
    detector, detector_params = sc.detector, dict(sc.detector_params)
    attacks = [dict(t) for t in attack_tables(sc.attack)]
    rates = sc.rates.model_dump()
    traffic = sc.traffic.explicit()
    control = sc.control.explicit()
    chassis = sc.chassis.explicit()
    for item in settings:
        key, eq, raw = item.partition("=")
        key = key.strip()
        _check(bool(eq) and bool(key), f"--set {item!r}: expected KEY=VALUE, e.g. defense.b=0.45")
        _check("\n" not in item and "\r" not in item,
               f"--set {item!r}: a value holds a newline; give each KEY=VALUE as its own --set")
        value = _toml_value(raw.strip())
        section, dot, name = key.partition(".")
        if not dot:
            plain = sorted(_TOP_KEYS - {"defense", "attack", "detector", *_SECTIONS})
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
        elif section == "rates":
            _set_nested(rates, name.split("."), value, item)
        elif section == "traffic":
            traffic[name] = value
        elif section == "control":
            control[name] = value
        elif section == "chassis":
            chassis[name] = value
        else:
            raise ScenarioError(f"--set {item!r}: unknown section {section!r}; use defense.KEY, detector.KEY, "
                                f"attack.KEY, rates.KEY, traffic.KEY, control.KEY, chassis.KEY or KEY")
    return sc.replace(defense=defense, defense_params=params, detector=detector, detector_params=detector_params,
                      attack=attack_value(attacks), rates=rates, traffic=traffic, control=control, chassis=chassis,
                      **top)


def _set_nested(table: dict[str, Any], path: list[str], value: Any, item: str) -> None:
    """`table[a][b]... = value` along `path`, making the inner tables it needs."""
    for key in path[:-1]:
        inner = table.setdefault(key, {})
        _check(isinstance(inner, dict), f"--set {item!r}: {key!r} is a value, not a table")
        table = inner
    table[path[-1]] = value


def add_attacks(sc: Scenario, specs: list[str]) -> Scenario:
    """`sc` with the `--attack` specs composed after its own attacks (hooks run in that order)."""
    if not specs:
        return sc
    tables = [*attack_tables(sc.attack), *(attack_spec_to_dict(spec) for spec in specs)]
    return sc.replace(attack=attack_value(tables))


def shipped_scenarios() -> list[str]:
    root = resources.files("testbed.eval.run") / "scenarios"
    return sorted(p.name.removesuffix(".toml") for p in root.iterdir() if p.name.endswith(".toml"))


def load_scenario(name_or_path: str) -> Scenario:
    """A shipped scenario by name, or a TOML file by path."""
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        _check(path.is_file(), f"scenario file not found: {path}")
        try:
            text, name = path.read_text(encoding="utf-8"), _name_of_stem(path.stem)
        except (UnicodeDecodeError, OSError) as exc:
            raise ScenarioError(f"scenario file {path} is not a text TOML file: {exc}") from None
    else:
        res = resources.files("testbed.eval.run") / "scenarios" / f"{name_or_path}.toml"
        _check(res.is_file(),
               f"unknown scenario {name_or_path!r}; shipped: {', '.join(shipped_scenarios())} (or a .toml path)")
        text, name = res.read_text(), name_or_path
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"malformed TOML in {name_or_path}: {exc}") from None
    except RecursionError:
        raise ScenarioError(f"malformed TOML in {name_or_path}: arrays or tables nested too deep") from None
    return scenario_from_dict(data, name)


def _name_of_stem(stem: str) -> str:
    """A scenario file's stem as a run name (`NAME_PATTERN`): each run of other characters becomes '-', leading
    dots and dashes go (`my scen ário.toml` -> my-scen-rio, `.hidden.toml` -> hidden); 'scenario' if none is left."""
    name = re.sub(r"[^A-Za-z0-9_.@+=,-]+", "-", stem).lstrip(".-")[:120]
    return name or "scenario"
