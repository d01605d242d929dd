"""What `ld3 vehicle --scenario FILE` reads of a scenario TOML: the loop's `[rates]`, `[control]` and `[defense]`
tables (the rest of a scenario describes the simulated world, which a vehicle does not have)."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from testbed.control.config import ControlConfig
from testbed.defense.registry import DEFENSES, defense_settings
from testbed.errors import UserError
from testbed.rates import Rates

MAX_BYTES = 1 << 20
"""A scenario file larger than this is refused unread."""


def _model(path: Path, section: str, model: type[BaseModel], table: Any) -> Any:
    if not isinstance(table, dict):
        raise UserError(f"{path}: [{section}] must be a table, got {table!r}")
    try:
        return model.model_validate(table)
    except ValidationError as exc:
        err = exc.errors()[0]
        key = ".".join(str(part) for part in err["loc"])
        raise UserError(f"{path}: [{section}] {key + ': ' if key else ''}{err['msg']}") from None


def loop_tables(path: Path) -> dict[str, Any]:
    """`rates`, `control`, `defense_params` and `defense` (the `[defense]` kind, or a name; absent if the file
    names none) from the scenario at `path`, each validated; a one-line UserError naming the key otherwise."""
    try:
        if path.stat().st_size > MAX_BYTES:
            raise UserError(f"{path}: larger than {MAX_BYTES} bytes; not a scenario")
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise UserError(f"cannot read scenario {path}: {exc.strerror}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: not a TOML file ({exc})") from None
    out: dict[str, Any] = {"rates": _model(path, "rates", Rates, data.get("rates", {})),
                           "control": _model(path, "control", ControlConfig, data.get("control", {}))}
    defense = data.get("defense")
    if isinstance(defense, dict):
        params = dict(defense)
        out["defense"] = params.pop("kind", "ld3")
        out["defense_params"] = params
    elif defense is not None:
        out["defense"] = defense
    name = out.get("defense")
    if name is not None and name not in DEFENSES:
        raise UserError(f"{path}: unknown defense {name!r}; known: {', '.join(DEFENSES.names())}")
    if name is not None:
        defense_settings(name, out.get("defense_params", {}))
    return out
