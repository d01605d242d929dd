"""A scenario written back as the TOML that `ld3 run FILE.toml` loads to the same scenario."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import tomli_w

from testbed.attacks.spec import attack_tables, attack_value
from testbed.defense.registry import explicit_table
from testbed.eval.run.scenario import Scenario


def scenario_document(sc: Scenario) -> dict[str, Any]:
    """The scenario as a TOML document: every set field, components as tables with `kind`, and the defense's
    parameters written out in full (`testbed.defense.registry.explicit_table`)."""
    doc: dict[str, Any] = {"name": sc.name, "track": sc.track, "vehicle": sc.vehicle, "speed": float(sc.speed),
                           "duration": float(sc.duration), "condition": sc.condition, "seed": sc.seed,
                           "start_s": float(sc.start_s), "localization": sc.localization}
    if sc.lane is not None:
        doc["lane"] = sc.lane
    if sc.stop_at is not None:
        doc["stop_at"], doc["stop_decel"] = float(sc.stop_at), float(sc.stop_decel)
    if sc.rates.explicit():
        doc["rates"] = sc.rates.explicit()
    if sc.traffic.explicit():
        doc["traffic"] = sc.traffic.explicit()
    if sc.control.explicit():
        doc["control"] = sc.control.explicit()
    if sc.chassis.explicit():
        doc["chassis"] = sc.chassis.explicit()
    doc["detector"] = {"kind": sc.detector, **sc.detector_params}
    doc["defense"] = {"kind": sc.defense, **explicit_table(sc.defense, sc.defense_params)}
    if sc.attack:
        doc["attack"] = attack_value([dict(t) for t in attack_tables(sc.attack)])
    return doc


def write_scenario(path: Path, sc: Scenario, comment: str = "") -> None:
    """Write `sc` as TOML (with `comment` lines on top)."""
    head = "".join(f"# {line}\n" for line in comment.splitlines())
    path.write_text(head + tomli_w.dumps(scenario_document(sc)))
