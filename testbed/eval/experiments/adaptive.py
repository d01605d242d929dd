"""The security-margin campaign (`ld3 campaign adaptive`): a worst-case attack search per road × defense ×
threat model, and the table of what the best attacker found against each defense.

Each cell is one `AttackSearch` into `OUT/<road>/<defense>/<threat>/` (resumable); when it completes its
`summary.json` records the worst deviation found before detection, the worst at all, the consequence and the
replay command. Threat models that give the attacker both the localization and lane-detection inputs are outside
LD3's threat model and are marked as such in the table, never hidden.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shlex
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from testbed.attacks.threat import parse_threat, within_ld3_threat_model
from testbed.defense.config import PAPER_MODE
from testbed.errors import UserError
from testbed.eval.campaign.driver import CampaignRun, load_summary
from testbed.eval.run.outputs import provenance
from testbed.eval.run.scenario import load_scenario
from testbed.eval.search.attack_search import AttackSearch, SearchSpec, attack_spec
from testbed.eval.search.report import write_search_report

ROADS = ("local", "highway", "urban-curvy")
THREATS = ("gnss", "msf-output", "ld-output", "msf-output,ld-output")
DEFAULT_BUDGET = 24
"""Trials per cell by default (`--budget` sets it): 60 cells make 1,440 closed-loop runs."""
DURATION_S = 45.0
"""Simulated time of every trial: long enough for an attack started up to 30 s in to act."""


@dataclass(frozen=True)
class Victim:
    """A row of the table: its label, folder name, defense and `[defense]` overrides."""

    label: str
    slug: str
    defense: str
    params: tuple[tuple[str, Any], ...] = ()


VICTIMS = (
    Victim("none", "none", "none"),
    Victim("NaiveAR", "naive-ar", "ld3-naive-ar"),
    Victim("SAVIOR", "savior", "savior"),
    Victim("LD3 paper mode", "ld3-paper", "ld3", tuple(PAPER_MODE.items())),
    Victim("LD3 default", "ld3", "ld3"),
)


def adaptive_runs(detector: str, budget: int = DEFAULT_BUDGET) -> list[CampaignRun]:
    """One campaign run per cell: its id `road/defense/threat`, the victim scenario, the threat and budget."""
    runs = []
    for road in ROADS:
        base = load_scenario(road)
        for victim in VICTIMS:
            sc = base.replace(defense=victim.defense, defense_params=dict(victim.params), localization="msf",
                              detector=detector, duration=DURATION_S)
            for threat in THREATS:
                slug = threat.replace(",", "+")
                runs.append(CampaignRun(f"{road}/{victim.slug}/{slug}", sc,
                                        {"road": road, "victim": victim.label, "threat": threat, "trials": budget}))
    return runs


def with_budget(runs: Sequence[CampaignRun], budget: int) -> list[CampaignRun]:
    """The cells with `budget` trials each."""
    if budget < 1:
        raise UserError(f"--budget must be >= 1 trial per search, got {budget}")
    return [dataclasses.replace(r, tags={**r.tags, "trials": budget}) for r in runs]


def run_cells(runs: Sequence[CampaignRun], out: Path, *, workers: int | None, backend: str, address: str | None,
              timeout: float | None, progress: bool) -> list[tuple[CampaignRun, dict[str, Any]]]:
    """Run (or resume) each cell's search; a cell whose threat model no family can act under is recorded as such."""
    done = []
    for run in runs:
        folder = out / run.run_id
        summary = load_summary(folder)
        if not isinstance(summary, dict) or summary.get("trials", 0) < run.tags["trials"]:
            summary = _search_cell(run, folder, workers=workers, backend=backend, address=address, timeout=timeout,
                                   progress=progress)
        done.append((run, summary))
    return done


def _search_cell(run: CampaignRun, folder: Path, **options: Any) -> dict[str, Any]:
    threat = parse_threat(run.tags["threat"])
    base = {"road": run.tags["road"], "victim": run.tags["victim"], "threat": run.tags["threat"],
            "in_ld3_threat_model": within_ld3_threat_model(threat), "git_commit": provenance()["git_commit"]}
    try:
        search = AttackSearch(SearchSpec(run.scenario, threat, run.tags["trials"]), folder / "search", **options)
    except UserError as exc:
        summary = {**base, "trials": run.tags["trials"], "not_applicable": str(exc)}
    else:
        outcomes = search.run()
        write_search_report(search)
        best, scored = search.best(), [o for o in outcomes if o.score is not None]
        overall = max(scored, key=lambda o: o.max_dev_m, default=None)
        summary = {**base, "trials": len(outcomes), "failed": len(outcomes) - len(scored),
                   "worst_undetected_m": best.dev_before_m if best else None,
                   "worst_attack": attack_spec(best.attack) if best else None,
                   "worst_detected": best.detected if best else None,
                   "worst_consequence": best.consequence if best else None,
                   "worst_overall_m": overall.max_dev_m if overall else None,
                   "worst_overall_attack": attack_spec(overall.attack) if overall else None,
                   "undetected_departures": sum(o.undetected_departure for o in scored),
                   "straddle_m": best.straddle_m if best else None,
                   "replay": shlex.join(["ld3", "run", str(folder / "search" / "best.toml")])}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def _cell(s: dict[str, Any], out: Path) -> str:
    if "not_applicable" in s:
        return "n/a"
    if s.get("worst_undetected_m") is None:
        return "all runs failed"
    flag = " **departs**" if s["undetected_departures"] else ""
    return (f"{s['worst_undetected_m']:.2f} / {s['worst_overall_m']:.2f}{flag} "
            f"([replay]({Path(os.path.relpath(shlex.split(s['replay'])[-1], out)).as_posix()}))")


def adaptive_table(done: list[tuple[CampaignRun, dict[str, Any]]], out: Path) -> str:
    """Per road: defenses × threat models, each cell the worst |D| before detection / worst |D| at all (m)."""
    cells = {(r.tags["road"], r.tags["victim"], r.tags["threat"]): s for r, s in done}
    budget = max((r.tags["trials"] for r, _ in done), default=0)
    lines = [f"Worst-case attack search per cell ({budget} trials; Optuna TPE over the families the threat model "
             "allows): worst physical |D| reached before detection / worst |D| at all (m); **departs**: some trial "
             "reached the lane straddle deviation undetected. † outside LD3's threat model (the attacker also "
             "controls lane-detection inputs): measured, not a defeat of LD3's design. Replay a cell with "
             "`ld3 run <cell>/search/best.toml`.", ""]
    threats = [t for t in THREATS if any(k[2] == t for k in cells)]
    for road in ROADS:
        rows = [v.label for v in VICTIMS if any(k[:2] == (road, v.label) for k in cells)]
        if not rows:
            continue
        head = [t + ("" if within_ld3_threat_model(parse_threat(t)) else " †") for t in threats]
        lines += [f"**{road}**", "", "| defense | " + " | ".join(head) + " |", "|---|" + "---|" * len(threats)]
        for label in rows:
            row = [_cell(cells[(road, label, t)], out) if (road, label, t) in cells else "–" for t in threats]
            lines.append(f"| {label} | " + " | ".join(row) + " |")
        lines.append("")
    return "\n".join(lines)
