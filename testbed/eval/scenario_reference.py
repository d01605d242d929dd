"""The scenario file's reference, generated from the registries: every key with its type, default and unit
(markdown for docs/components.md, `ld3 components`) and a JSON Schema of the TOML (`ld3 schema`)."""

from __future__ import annotations

import dataclasses
from typing import Any

from testbed.attacks.registry import ATTACKS
from testbed.defense.config import DefenseConfig
from testbed.defense.registry import DEFENSES
from testbed.eval.scenario import ALWAYS_READ, Scenario
from testbed.localization.registry import LOCALIZATIONS
from testbed.params import reference_rows
from testbed.perception.registry import DETECTORS
from testbed.presets import TRACKS, VEHICLES
from testbed.registry import Registry

TOP_LEVEL: dict[str, str] = {
    "name": "run name (default: the file's stem)",
    "track": "track preset, `NAME` or `NAME@SEED` (a seed > 0 draws a held-out variant)",
    "vehicle": "vehicle",
    "speed": "target speed (m/s)",
    "duration": "simulated duration (s)",
    "condition": "lighting and weather of the camera (`ld3 scenarios` lists them)",
    "seed": "seed of every random draw of the run",
    "lane": "lane driven, 0 = rightmost (default: the track's ego lane)",
    "start_s": "start position along the road (m)",
    "detector": "lane detector: a name, or a [detector] table with `kind` and its parameters",
    "localization": "localization source",
    "defense": "defense: a name, or a [defense] table with `kind` (default ld3) and parameters",
    "attack": "an [attack] table with `kind` and its parameters, a list of them (composed in order), or none",
    "rates": "[rates] control_hz (100), camera_hz (20), physics_hz (100), command_hold_s (0), and a "
             "[rates.localization] table of sensor rates and noise",
    "stop_at": "time of a planned in-lane stop (s), independent of any defense",
    "stop_decel": "deceleration of the planned stop (m/s²)",
}
"""What each top-level key means, with its unit: the one place the scenario's plain keys are described."""


def _choices(registry: Registry) -> str:
    return ", ".join(f"`{n}`" for n in registry.names())


_CHOICES = {"track": TRACKS, "vehicle": VEHICLES, "detector": DETECTORS, "localization": LOCALIZATIONS,
            "defense": DEFENSES, "attack": ATTACKS}


def _table(rows: list[tuple[str, str, str, str]], extra: list[str] | None = None) -> list[str]:
    head = "| key | type | default | meaning |" + (" read by |" if extra else "")
    lines = [head, "|---|---|---|---|" + ("---|" if extra else "")]
    for i, row in enumerate(rows):
        key, typ, default, meaning = (cell.replace("|", "\\|") for cell in row)
        lines.append(f"| `{key}` | {typ} | `{default}` | {meaning} |" + (f" {extra[i]} |" if extra else ""))
    return lines


def reference_markdown() -> str:
    """Every scenario key: the top level, [defense] (and which defenses read each key), [detector] and
    [attack] per kind."""
    out = ["## Scenario keys", "", "Top level of the scenario TOML:", ""]
    rows = []
    for f in dataclasses.fields(Scenario):
        if f.name.endswith("_params"):
            continue
        default = f.default if f.default is not dataclasses.MISSING else (
            "required" if f.default_factory is dataclasses.MISSING else f.default_factory())
        if f.name == "name":
            default = "the file's stem"
        meaning = TOP_LEVEL[f.name]
        if f.name in _CHOICES:
            meaning += f"; one of {_choices(_CHOICES[f.name])}"
        rows.append((f.name, str(f.type), repr(default) if f.name != "track" else "required", meaning))
    out += _table(rows)
    readers = [", ".join(f"`{d.name}`" for d in DEFENSES if key in d.reads or key in ALWAYS_READ) or "–"
               for key in DefenseConfig.model_fields]
    out += ["", "`[defense]` (a key no chosen defense reads is refused):", ""]
    out += _table(reference_rows(DefenseConfig), readers)
    for title, registry in (("detector", DETECTORS), ("attack", ATTACKS)):
        for c in registry:
            rows = reference_rows(c.params)
            if rows:
                out += ["", f"`[{title}]` with kind = `{c.name}`:", "", *_table(rows)]
    return "\n".join(out)


def _with_kind(kind: str, model_schema: dict[str, Any], defs: dict[str, Any]) -> dict[str, Any]:
    """An object schema: `kind` fixed to `kind` plus the model's properties."""
    defs.update(model_schema.pop("$defs", {}))
    props = {"kind": {"const": kind}, **model_schema.get("properties", {})}
    return {"type": "object", "properties": props, "required": ["kind", *model_schema.get("required", [])],
            "additionalProperties": False}


def json_schema() -> dict[str, Any]:
    """A JSON Schema (draft 2020-12) of the scenario TOML, from the registries and the parameter models."""
    defs: dict[str, Any] = {}
    names = {key: {"enum": list(registry.names())} for key, registry in _CHOICES.items() if key != "attack"}
    props: dict[str, Any] = {f.name: {"description": TOP_LEVEL[f.name]} for f in dataclasses.fields(Scenario)
                             if not f.name.endswith("_params")}
    for key in ("speed", "duration", "start_s", "stop_at", "stop_decel"):
        props[key]["type"] = "number"
    props["seed"]["type"] = "integer"
    props["lane"]["type"] = "integer"
    props["name"]["type"] = props["condition"]["type"] = "string"
    props["track"].update(type="string", pattern=f"^({'|'.join(TRACKS.names())})(@[0-9]+)?$")
    props["vehicle"].update(names["vehicle"])
    props["localization"].update(names["localization"])
    props["rates"]["type"] = "object"
    defense_table = DefenseConfig.model_json_schema()
    defense_table["properties"] = {"kind": names["defense"], **defense_table["properties"]}
    props["defense"]["anyOf"] = [names["defense"], defense_table]
    props["detector"]["anyOf"] = [names["detector"]] + [
        _with_kind(c.name, c.params.model_json_schema(), defs) for c in DETECTORS]
    tables = [_with_kind(c.name, c.params.model_json_schema(), defs) for c in ATTACKS]
    props["attack"]["anyOf"] = [*tables, {"type": "array", "minItems": 1, "items": {"anyOf": tables}}]
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": "LD3 testbed scenario",
            "type": "object", "properties": props, "required": ["track"], "additionalProperties": False,
            "$defs": defs}
