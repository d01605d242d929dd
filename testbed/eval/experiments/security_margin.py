"""The security-margin table (`ld3 security-margin`): a worst-case attack search with the objective `loss` per
road × threat model × defense × sampler seed, against the oracle lane detector, and per road × threat × defense
the losses, the worst |D| at all, the worst |D| before detection and LD3's deviation bound at the road's speed
(the bound is on what an attacker of the pose does before the alarm: none for the lines' attacker alone).

Each cell is one `AttackSearch` in `OUT/<road>/<defense>/<threat>/seed<N>/search` (it resumes itself); a cell
that completed its budget records its figures in `summary.json` beside it and is not run again. The threat
models LD3 claims make the table: its localization attacker (`gnss`, `msf-output`) and the lane detector's attacker
alone (`ld-output`); `msf-output,ld-output` (the attacker of both) is reported beside it, outside the threat model.
"""

from __future__ import annotations

import csv
import functools
import json
import math
import os
import shlex
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from testbed.attacks.threat import parse_threat, reaches_pose, within_ld3_threat_model
from testbed.defense.config import PAPER_MODE
from testbed.errors import UserError
from testbed.eval.campaign.driver import RunExecutor, campaign_backend, load_summary, run_and_write_data
from testbed.eval.experiments.adaptive import Victim
from testbed.eval.run.scenario import Scenario, load_scenario
from testbed.eval.search.attack_search import AttackSearch, SearchSpec, attack_spec, csv_cell
from testbed.eval.search.bound_table import BoundSetting, bound_on_car, bound_rows, bound_setting
from testbed.eval.search.report import write_search_report
from tracks.presets import PRESETS, parse_track_spec

HELD_OUT = ("highway@101", "urban-curvy@101")
"""Two held-out layouts: seeded variants of the presets whose drives are fastest and most curved."""
ROADS = (*PRESETS, *HELD_OUT)
THREATS = ("gnss", "msf-output", "ld-output")
BESIDE = ("msf-output,ld-output",)
"""Threat models reported beside the table: outside LD3's (the attacker also controls the lane detector)."""
SEEDS = (0, 1, 2)
BUDGET = 120
DURATION_S = 45.0
"""Simulated time of every trial: long enough for an attack started up to 30 s in to act."""


DEFENSES = (
    Victim("LD3 default", "ld3", "ld3"),
    Victim("LD3 paper mode", "ld3-paper", "ld3", tuple(PAPER_MODE.items())),
    Victim("NaiveAR", "naive-ar", "ld3-naive-ar"),
    Victim("SAVIOR", "savior", "savior"),
)


@dataclass(frozen=True)
class Cell:
    """One search: road, defense, threat model, sampler seed, trials; its victim scenario and folder."""

    road: str
    defended: Victim
    threat: str
    seed: int
    budget: int

    @property
    def folder(self) -> Path:
        return Path(self.road, self.defended.slug, self.threat.replace(",", "+"), f"seed{self.seed}")

    def victim(self) -> Scenario:
        return victim_scenario(self.road, self.defended)


def victim_scenario(road: str, defended: Victim) -> Scenario:
    """The road's shipped scenario (its preset's; a held-out layout's family) with the defense, MSF
    localization, the oracle detector and `DURATION_S`."""
    name, seed = parse_track_spec(road)
    base = load_scenario(name)
    return base.replace(name=road.replace("@", "-"), track=road if seed else base.track, defense=defended.defense,
                        defense_params=dict(defended.params), localization="msf", detector="oracle",
                        duration=DURATION_S)


def _pick(given: Sequence[str] | None, known: Sequence[str], what: str) -> list[str]:
    if not given:
        return list(known)
    unknown = [g for g in given if g not in known]
    if unknown:
        raise UserError(f"unknown {what} {', '.join(unknown)}; known: {', '.join(known)}")
    return list(dict.fromkeys(given))


def plan_cells(*, roads: Sequence[str] | None = None, defenses: Sequence[str] | None = None,
               threats: Sequence[str] | None = None, seeds: Sequence[int] | None = None,
               budget: int = BUDGET) -> list[Cell]:
    """The cells of the selection (each default: all), in table order; UserError for an unknown name."""
    if budget < 1:
        raise UserError(f"--budget must be >= 1 trial per search, got {budget}")
    seeds = list(SEEDS if not seeds else dict.fromkeys(seeds))
    if min(seeds) < 0:
        raise UserError(f"--seeds must be >= 0, got {min(seeds)}")
    slugs = {d.slug: d for d in DEFENSES}
    chosen = [slugs[s] for s in _pick(defenses, list(slugs), "defense")]
    for threat in threats or ():
        parse_threat(threat)
    return [Cell(road, d, t, s, budget) for road in _pick(roads, ROADS, "road") for d in chosen
            for t in _pick(threats, (*THREATS, *BESIDE), "threat") for s in seeds]


def cell_summary(cell: Cell, search: AttackSearch) -> dict[str, Any]:
    """A finished cell's figures: trials, failed runs, losses, the worst |D| at all and before detection, and the
    worst trial (the search's best under `loss`: a loss first, then the farthest) with its replay."""
    outcomes = search.sorted_outcomes()
    scored = [o for o in outcomes if o.score is not None]
    worst = search.best()
    return {"road": cell.road, "defense": cell.defended.label, "threat": cell.threat, "seed": cell.seed,
            "trials": len(outcomes), "failed": len(outcomes) - len(scored),
            "losses": sum(bool(o.loss) for o in scored),
            "worst_max_dev_m": max((o.max_dev_m for o in scored), default=None),
            "worst_dev_before_m": max((o.dev_before_m for o in scored), default=None),
            "straddle_m": next((o.straddle_m for o in scored if o.straddle_m is not None), None),
            "worst_attack": attack_spec(worst.attack) if worst else None,
            "worst_consequence": worst.consequence if worst else None,
            "replay": shlex.join(["ld3", "run", str(search.out / "best.toml")]) if worst else None}


def run_cell(cell: Cell, out: Path, execute: RunExecutor = run_and_write_data, **options: Any) -> dict[str, Any]:
    """The cell's figures: read back when it completed its budget, else searched (resuming) and recorded; a
    threat model no family can act under on the road is recorded as not applicable."""
    folder = out / cell.folder
    done = load_summary(folder)
    if isinstance(done, dict) and done.get("trials", 0) >= cell.budget:
        return done
    try:
        search = AttackSearch(SearchSpec(cell.victim(), parse_threat(cell.threat), cell.budget, seed=cell.seed),
                              folder / "search", execute=execute, **options)
    except UserError as exc:
        summary: dict[str, Any] = {"road": cell.road, "defense": cell.defended.label, "threat": cell.threat,
                                   "seed": cell.seed, "trials": cell.budget, "not_applicable": str(exc)}
    else:
        search.run()
        write_search_report(search)
        summary = cell_summary(cell, search)
    folder.mkdir(parents=True, exist_ok=True)
    _write_atomic(folder / "summary.json", json.dumps(summary, indent=2) + "\n")
    return summary


@dataclass(frozen=True)
class Row:
    """One road × defense × threat over its seeds (None: no figures)."""

    road: str
    defense: str
    threat: str
    seeds: int
    trials: int
    failed: int
    losses: int | None
    worst_max_dev_m: float | None
    worst_dev_before_m: float | None
    bound_m: float | None
    straddle_m: float | None
    note: str = ""
    bound_on_car_m: float | None = None

    @property
    def in_threat_model(self) -> bool:
        return within_ld3_threat_model(parse_threat(self.threat))


def _max(values: Sequence[float | None]) -> float | None:
    kept = [v for v in values if v is not None]
    return max(kept) if kept else None


def table_rows(done: Sequence[tuple[Cell, dict[str, Any]]], bound: Callable[[Cell], float | None],
               car_bound: Callable[[Cell], float | None] = lambda cell: None) -> list[Row]:
    """Rows per road × defense × threat in cell order, the seeds' figures pooled; `bound` gives a cell's bound on
    the model, `car_bound` on the car."""
    groups: dict[tuple[str, str, str], list[tuple[Cell, dict[str, Any]]]] = {}
    for cell, summary in done:
        groups.setdefault((cell.road, cell.defended.label, cell.threat), []).append((cell, summary))
    rows = []
    for (road, defense, threat), members in groups.items():
        applicable = [s for _, s in members if "not_applicable" not in s]
        note = "" if applicable else f"n/a: {members[0][1]['not_applicable']}"
        rows.append(Row(road, defense, threat, len(members), sum(s["trials"] for s in applicable),
                        sum(s["failed"] for s in applicable),
                        sum(s["losses"] for s in applicable) if applicable else None,
                        _max([s["worst_max_dev_m"] for s in applicable]),
                        _max([s["worst_dev_before_m"] for s in applicable]), bound(members[0][0]),
                        _max([s["straddle_m"] for s in applicable]), note, car_bound(members[0][0])))
    return rows


def cell_bound(cell: Cell) -> float | None:
    """LD3's deviation bound at the victim's speed (inf in paper mode), None for a defense without LD3's checks or a
    threat that moves no pose (the car steers on the true one until the alarm)."""
    return _road_bound(cell.road, cell.defended) if reaches_pose(parse_threat(cell.threat)) else None


@functools.cache
def _road_setting(road: str, defended: Victim) -> tuple[Scenario, BoundSetting] | None:
    """The victim and its bound's setting; None for a defense without LD3's checks."""
    victim = victim_scenario(road, defended)
    try:
        return victim, bound_setting(victim)
    except UserError:
        return None


@functools.cache
def _road_bound(road: str, defended: Victim) -> float | None:
    found = _road_setting(road, defended)
    return None if found is None else bound_rows(found[1], [found[0].speed])[0].bound_m


def cell_bound_on_car(cell: Cell, cache: Path) -> float | None:
    """The bound at the victim's speed on its loop identified on the car (`ld3 bound --on-car`), kept in
    `cache`/<road>-<defense>.json; inf in paper mode, None for a defense without LD3's checks or a threat that moves
    no pose."""
    if not reaches_pose(parse_threat(cell.threat)):
        return None
    path = cache / f"{cell.road}-{cell.defended.slug}.json"
    if path.exists():
        kept = json.loads(path.read_text())
        return math.inf if kept["bound_on_car_m"] == "inf" else kept["bound_on_car_m"]
    found = _road_setting(cell.road, cell.defended)
    if found is None:
        return None
    victim, setting = found
    value = bound_on_car(setting, victim, victim.speed)
    cache.mkdir(parents=True, exist_ok=True)
    _write_atomic(path, json.dumps({"road": cell.road, "defense": cell.defended.label, "speed_mps": victim.speed,
                                    "bound_on_car_m": "inf" if math.isinf(value) else value}) + "\n")
    return value


def _m(v: float | None) -> str:
    return "–" if v is None else "unbounded" if math.isinf(v) else f"{v:.2f}"


HEADER = ("| road | defense | threat | seeds × trials | losses | worst max \\|D\\| (m) "
          "| worst \\|D\\| before detection (m) | bound (m) | bound on the car (m) | straddle (m) |")
RULE = "|---|---|---|---|---|---|---|---|---|---|"


def _line(r: Row) -> str:
    losses = r.note or ("–" if r.losses is None else f"**{r.losses}**" if r.losses else "0")
    failed = f" ({r.failed} failed)" if r.failed else ""
    return (f"| {r.road} | {r.defense} | {r.threat} | {r.seeds} × {r.trials // max(r.seeds, 1)}{failed} | {losses} "
            f"| {_m(r.worst_max_dev_m)} | {_m(r.worst_dev_before_m)} | {_m(r.bound_m)} | {_m(r.bound_on_car_m)} "
            f"| {_m(r.straddle_m)} |")


def table_markdown(rows: Sequence[Row]) -> str:
    """The table (threat models within LD3's) and the rows beside it (outside)."""
    inside = [r for r in rows if r.in_threat_model]
    outside = [r for r in rows if not r.in_threat_model]
    lines = ["# Security margin", "",
             "Worst-case attack search per cell (objective `loss`: any lane departure or contact, detected or not; "
             "oracle lane detector; MSF localization). Losses over every trial of every sampler seed; worst |D| "
             "over them; bound: `ld3 bound` at the road's speed on the linear model, and on the car's loop identified "
             "in simulation (`ld3 bound --on-car`; – for a defense without LD3's checks, and for the lines' attacker "
             "alone, who moves no pose the car steers on before the alarm). Each "
             "cell's searches: `<road>/<defense>/<threat>/seed<N>/search/report.md`.", ""]
    if inside:
        lines += [HEADER, RULE, *map(_line, inside), ""]
    if outside:
        lines += ["## Beside the table: outside LD3's threat model", "",
                  "The attacker also controls the lane detector's output: measured, not a defeat of LD3's design.",
                  "", HEADER, RULE, *map(_line, outside), ""]
    return "\n".join(lines)


def write_table(out: Path, rows: Sequence[Row]) -> Path:
    """table.md and table.csv in `out`, each replaced whole."""
    _write_atomic(out / "table.md", table_markdown(rows))
    fields = ["road", "defense", "threat", "in_threat_model", "seeds", "trials", "failed", "losses",
              "worst_max_dev_m", "worst_dev_before_m", "bound_m", "bound_on_car_m", "straddle_m", "note"]
    tmp = out / f".table.csv.tmp-{os.getpid()}"
    with tmp.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(fields)
        for r in rows:
            writer.writerow([csv_cell(getattr(r, f)) for f in fields])
    os.replace(tmp, out / "table.csv")
    return out / "table.md"


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.parent / f".{path.name}.tmp-{os.getpid()}"
    tmp.write_text(text)
    os.replace(tmp, path)


def security_margin(cells: Sequence[Cell], out: Path, *, execute: RunExecutor = run_and_write_data,
                    announce: Callable[[str], None] = lambda line: None,
                    bound: Callable[[Cell], float | None] = cell_bound,
                    car_bound: Callable[[Cell, Path], float | None] = cell_bound_on_car, **options: Any) -> Path:
    """Run (or resume) every cell, then write the table (`car_bound` keeps its figures in OUT/bounds); `options`
    go to each `AttackSearch`."""
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} is a file; name a folder")
    out.mkdir(parents=True, exist_ok=True)
    done = []
    with campaign_backend(options.get("backend", "local"), options.get("address")).kept_warm():
        for i, cell in enumerate(cells, 1):
            summary = run_cell(cell, out, execute, **options)
            done.append((cell, summary))
            announce(f"[{i}/{len(cells)}] {cell.folder.as_posix()}: "
                     + (summary["not_applicable"] if "not_applicable" in summary else
                        f"{summary['losses']} losses in {summary['trials']} trials, worst max |D| "
                        f"{_m(summary['worst_max_dev_m'])} m"))
    return write_table(out, table_rows(done, bound, lambda cell: car_bound(cell, out / "bounds")))
