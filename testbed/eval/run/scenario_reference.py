"""The scenario file's reference, generated from the registries: every key with its type, default and unit
(markdown for docs/components.md, `ld3 components`) and a JSON Schema of the TOML (`ld3 schema`)."""

from __future__ import annotations

from typing import Any

from testbed.attacks.registry import ATTACKS
from testbed.chassis import ChassisModel
from testbed.control.config import ControlConfig
from testbed.defense.config import ALWAYS_READ, DefenseConfig
from testbed.defense.registry import DEFENSES, defense_keys
from testbed.eval.run.scenario import Scenario
from testbed.localization.registry import LOCALIZATIONS
from testbed.params import reference_rows
from testbed.perception.detectors.registry import DETECTORS
from testbed.presets import TRACKS, VEHICLES
from testbed.rates import Rates
from testbed.registry import Registry
from testbed.traffic.config import TrafficConfig
from tracks.opendrive.load import PREFIX as XODR_PREFIX


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
    """Every scenario key: the top level, [rates], [traffic], [control], [chassis], [defense] (and which defenses
    read each key), [detector] and [attack] per kind."""
    out = ["## Scenario keys", "", "Top level of the scenario TOML:", ""]
    rows = []
    for key, typ, default, meaning in reference_rows(Scenario):
        if key.endswith("_params"):
            continue
        if key in _CHOICES:
            meaning += f"; one of {_choices(_CHOICES[key])}"
        default = {"name": "the file's stem", "track": "required", "rates": "see [rates]",
                   "traffic": "see [traffic]", "control": "see [control]", "chassis": "see [chassis]"}.get(key, default)
        typ = "table | list of tables | None" if key == "attack" else typ
        rows.append((key, typ, default, meaning))
    out += _table(rows)
    out += ["", "`[rates]`:", "", *_table(reference_rows(Rates))]
    out += ["", "`[traffic]` (same-direction cars; a table that places none, or names a lane the track lacks, is "
                "refused):", "", *_table(reference_rows(TrafficConfig))]
    out += ["", "`[control]`:", "", *_table(reference_rows(ControlConfig))]
    out += ["", "`[chassis]` (the simulated chassis; over CAN the profile says what the chassis reports):", "",
            *_table(reference_rows(ChassisModel))]
    readers = [", ".join(f"`{d.name}`" for d in DEFENSES
                         if (d.params is DefenseConfig and key in defense_keys(d)) or key in ALWAYS_READ) or "–"
               for key in DefenseConfig.model_fields]
    out += ["", "`[defense]` (a key no chosen defense reads is refused):", ""]
    out += _table(reference_rows(DefenseConfig), readers)
    for c in DEFENSES:
        rows = reference_rows(c.params) if c.params is not DefenseConfig else []
        if rows:
            out += ["", f"`[defense]` with kind = `{c.name}`:", "", *_table(rows)]
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
    model = Scenario.model_json_schema()
    defs.update(model.pop("$defs", {}))
    props: dict[str, Any] = {key: value for key, value in model["properties"].items()
                             if not key.endswith("_params")}
    for key in ("defense", "detector", "attack"):
        props[key] = {"description": props[key]["description"]}
    props["track"].update(pattern=f"^(({'|'.join(TRACKS.names())})(@[0-9]+)?|{XODR_PREFIX}.+)$")
    props["vehicle"].update(names["vehicle"])
    props["localization"].update(names["localization"])
    defs["TrafficConfig"]["properties"]["vehicle"].update(names["vehicle"])
    defense_table = DefenseConfig.model_json_schema()
    defense_table["properties"] = {"kind": names["defense"], **defense_table["properties"]}
    loop_keys = {k: v for k, v in defense_table["properties"].items() if k in ALWAYS_READ}
    own_tables = [_with_kind(c.name, c.params.model_json_schema(), defs) for c in DEFENSES
                  if c.params is not DefenseConfig and c.params.model_fields]
    for table in own_tables:
        table["properties"].update(loop_keys)
    props["defense"]["anyOf"] = [names["defense"], defense_table, *own_tables]
    props["detector"]["anyOf"] = [names["detector"]] + [
        _with_kind(c.name, c.params.model_json_schema(), defs) for c in DETECTORS]
    tables = [_with_kind(c.name, c.params.model_json_schema(), defs) for c in ATTACKS]
    props["attack"]["anyOf"] = [*tables, {"type": "array", "minItems": 1, "items": {"anyOf": tables}}]
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": "LD3 testbed scenario",
            "type": "object", "properties": props, "required": ["track"], "additionalProperties": False,
            "$defs": defs}
