"""The paper report of `ld3 paper`: for every table and figure of the paper, its values (paper_values.toml,
each under the label it comes from) beside ours from the finished campaign runs, with the figures and the
command that regenerates each part.
"""

from __future__ import annotations

import os
import tomllib
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.experiments.ablation import ATTACKS as ABLATION_ATTACKS
from testbed.eval.experiments.ablation import IN_LANE, VARIANTS, is_default
from testbed.eval.experiments.adaptive import adaptive_table
from testbed.eval.experiments.paper_figures import Stat, paper_vs_ours
from testbed.eval.experiments.roc import roc_table
from testbed.eval.experiments.stealthy_bound import LD_NOISE_STD, STEALTHY_TRACKS, fluctuation_stats, run_bound
from testbed.eval.report.summary_stats import (
    abs_or_none,
    consequences,
    finite,
    mean_sd,
    response_max_dev,
    stop_dev,
    undetected_dev,
)
from testbed.eval.run.consequence import ATTACK_GOAL_M, attack_succeeded
from testbed.eval.run.outputs import read_trajectory
from testbed.eval.run.summary import RunSummary


@dataclass(frozen=True)
class CampaignResult:
    """One campaign of the paper: its folder, the command that regenerates it, its planned and done runs."""

    name: str
    folder: Path
    command: str
    planned: list[CampaignRun]
    done: list[tuple[CampaignRun, Any]]
    """(run, its `RunSummary`); for a campaign of searches (adaptive), (cell, the cell's summary dict)."""


Done = list[tuple[CampaignRun, RunSummary]]
Section = Callable[[dict[str, CampaignResult], dict[str, Any], Path], str]

SIM_SETTINGS = {"ld3": "ld3", "naive": "ld3-naive-ar", "none": "none", "benign": "benign"}
"""paper_values key -> our sim-table setting."""


def load_paper_values() -> dict[str, Any]:
    """The paper's values, by section; each section names its `label` in ld3_paper.tex."""
    values = tomllib.loads((resources.files("testbed.eval.experiments") / "paper_values.toml").read_text())
    unlabelled = [name for name, section in values.items() if "label" not in section]
    if unlabelled:
        raise ValueError(f"paper_values.toml sections without a label: {unlabelled}")
    return values


def _stat(values: Sequence[float]) -> Stat:
    return (float(values[0]), float(values[1]))


def _f(stat: Stat, digits: int = 2) -> str:
    return "–" if stat is None else f"{stat[0]:.{digits}f}, {stat[1]:.{digits}f}"


def _header(title: str, label: str, results: Sequence[CampaignResult], out: Path) -> str:
    lines = [f"## {title}", "", f"Paper: `{label}`."]
    for res in results:
        lines.append(f"Ours: {len(res.done)} of {len(res.planned)} runs of campaign `{res.name}` "
                     f"([report]({_rel(res.folder / 'report.md', out)})); regenerate: `{res.command}`")
    return "\n".join(lines) + "\n"


def _rel(path: Path, out: Path) -> str:
    return Path(os.path.relpath(path, out)).as_posix()


def _tagged(done: Done, **tags: Any) -> list[RunSummary]:
    return [s for r, s in done if all(r.tags.get(k) == v for k, v in tags.items())]


# ---- simulator table -------------------------------------------------------------------------------------
def sim_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    paper, res = values["sim_table"], results["sim-table"]
    lines = [_header("Simulator table: trace injection, LD3 / NaiveAR / none, and benign LD3", paper["label"],
                     [res], out),
             f"Max dev = max |physical D| (m), (mean, std); the paper ran {paper['runs_per_setting']} per setting. "
             "Each row's runs: the campaign's runs matching its glob (`--runs GLOB`).", "",
             "| scenario (ours) | setting | lane straddle dev paper / ours | max dev paper | max dev ours "
             "| consequence paper | consequences ours | runs | glob |", "|---|---|---|---|---|---|---|---|---|"]
    labels, paper_stats, our_stats = [], [], []
    for row in paper["rows"]:
        for key, setting in SIM_SETTINGS.items():
            sums = _tagged(res.done, scenario=row["ours"], setting=setting)
            ours = mean_sd(s.max_abs_dev_m for s in sums)
            straddle = f"{sums[0].lane_straddle_dev_m:.2f}" if sums else "–"
            glob = f"{row['ours']}/{setting}-*"
            lines.append(f"| {row['scenario']} ({row['ours']}) | {setting} | {row['lane_straddle_dev']:.2f} / "
                         f"{straddle} | {_f(_stat(row[key]['max_dev']))} | {_f(ours)} | {row[key]['consequence']} "
                         f"| {consequences(sums) if sums else '–'} | {len(sums)} | `{glob}` |")
            labels.append(f"{row['scenario']} {key}")
            paper_stats.append(_stat(row[key]["max_dev"]))
            our_stats.append(ours)
    paper_vs_ours(out / "sim_table.png", "Simulator table: max |D| per scenario and setting", labels, paper_stats,
                  our_stats, "max dev (m)")
    lines += ["", "![simulator table](sim_table.png)"]
    return "\n".join(lines)


# ---- chassis table ---------------------------------------------------------------------------------------
def ar_deceleration(run_dir: Path) -> float | None:
    """Mean deceleration of the response (m/s²): speed at its onset over the time to standstill or the end."""
    traj = pd.read_csv(run_dir / "trajectory.csv", usecols=["t", "speed", "mode"])
    ar = traj[traj["mode"] != "normal"]
    if len(ar) < 2 or ar["t"].iloc[-1] <= ar["t"].iloc[0]:
        return None
    return float((ar["speed"].iloc[0] - ar["speed"].iloc[-1]) / (ar["t"].iloc[-1] - ar["t"].iloc[0]))


def chassis_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    paper, res = values["chassis_table"], results["chassis"]
    lines = [_header("Chassis table over CAN: dev chassis, 2 and 4 m/s", paper["label"], [res], out),
             f"The paper repeated LD3 under attack {paper['ld3_repetitions']} times and the other settings once. "
             "Deviations |physical D| in m, (mean, std); the paper's no-defense column is one value for max and "
             "stop (the operator's e-stop).", "",
             "| speed | quantity | paper | ours | runs |", "|---|---|---|---|---|"]
    labels, paper_stats, our_stats = [], [], []
    for row in sorted(paper["rows"], key=lambda r: r["speed"]):
        speed = float(row["speed"])
        ld3, naive = _tagged(res.done, speed=speed, setting="ld3"), _tagged(res.done, speed=speed, setting="naive")
        none, benign = _tagged(res.done, speed=speed, setting="none"), _tagged(res.done, speed=speed, setting="benign")
        ld3_dirs = [res.folder / r.run_id for r, _ in res.done
                    if r.tags["speed"] == speed and r.tags["setting"] == "ld3"]
        rows: list[tuple[str, Stat, Stat, int]] = [
            ("LD3 detection dev", _stat(row["ld3_detection_dev"]), mean_sd(s.detection_dev_m for s in ld3),
             len(ld3)),
            ("LD3 max dev (response)", _stat(row["ld3_max_dev"]), mean_sd(response_max_dev(s) for s in ld3), len(ld3)),
            ("LD3 stop dev", _stat(row["ld3_stop_dev"]), mean_sd(stop_dev(s) for s in ld3), len(ld3)),
            ("LD3 response deceleration (m/s²)", None, mean_sd(ar_deceleration(d) for d in ld3_dirs), len(ld3)),
            ("NaiveAR max dev (response)", None, mean_sd(response_max_dev(s) for s in naive), len(naive)),
            ("NaiveAR stop dev", None, mean_sd(stop_dev(s) for s in naive), len(naive)),
            ("no defense max dev", (row["none_max_dev"], 0.0), mean_sd(s.max_abs_dev_m for s in none), len(none)),
            ("no defense stop dev", (row["none_max_dev"], 0.0), mean_sd(stop_dev(s) for s in none), len(none)),
            ("benign LD3 max dev", (row["benign_max_dev"], 0.0), mean_sd(s.max_abs_dev_m for s in benign),
             len(benign)),
            ("benign LD3 stop dev", (row["benign_stop_dev"], 0.0), mean_sd(stop_dev(s) for s in benign), len(benign)),
        ]
        for name, p, o, n in rows:
            paper_text = "< 3 (AR deceleration)" if name.startswith("LD3 response deceleration") else _f(p, 3)
            lines.append(f"| {speed:g} m/s | {name} | {paper_text} | {_f(o, 3)} | {n} |")
            if p is not None:
                labels.append(f"{speed:g} m/s {name}")
                paper_stats.append(p)
                our_stats.append(o)
    paper_vs_ours(out / "chassis_table.png", "Chassis table over CAN", labels, paper_stats, our_stats, "|D| (m)")
    lines += ["", "![chassis table](chassis_table.png)"]
    return "\n".join(lines)


# ---- FusionRipper detection and response ----------------------------------------------------------------
def fr_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    paper, replay = values["detection_response"], values["trace_replay"]
    closed, sim = results["fusionripper-ld3"], results["sim-table"]
    tracks = sorted({r.tags["track"] for r, _ in closed.done})
    lines = [_header("FusionRipper detection and response", f"{paper['label']} (KAIST traces), "
                     f"{replay['label']} (trace replay)", [closed, sim], out),
             "**Closed loop**: FusionRipper through the MSF against LD3 (`fusionripper-ld3`). The paper's column is "
             "its trace evaluation (" + "; ".join(paper["text"]) + ").", "",
             "| quantity | paper | " + " | ".join(f"ours {t}" for t in tracks) + " |",
             "|---|---|" + "---|" * len(tracks)]
    per_track = {t: _tagged(closed.done, track=t) for t in tracks}

    def row(name: str, paper_text: str, cell: Callable[[str, list[RunSummary]], str]) -> None:
        lines.append(f"| {name} | {paper_text} | " + " | ".join(cell(t, per_track[t]) for t in tracks) + " |")

    def over(field: Callable[[RunSummary], float | None], limit: Callable[[RunSummary], float]):
        return lambda t, sums: f"{sum((field(s) or 0.0) > limit(s) for s in sums)}/{len(sums)}"

    row("detected", "all (TPR 100 %)", lambda t, sums: f"{sum(bool(s.detected) for s in sums)}/{len(sums)}")
    row("detection dev (mean, std)", f"mean < {paper['detection_dev_mean_below']} on every trace",
        lambda t, sums: _f(mean_sd(s.detection_dev_m for s in sums)))
    row("detected beyond lane straddle", "0", over(lambda s: s.detection_dev_m, lambda s: s.lane_straddle_dev_m))
    row("response max dev (mean, std)", "–", lambda t, sums: _f(mean_sd(s.ar_max_dev_m for s in sums)))
    row("response max dev beyond lane straddle", f"{paper['highway_ar_max_over_straddle']} (highway traces)",
        over(lambda s: s.ar_max_dev_m, lambda s: s.lane_straddle_dev_m))
    def beyond_goal(track: str, sums: list[RunSummary]) -> str:
        hits = sum(attack_succeeded(track, s.max_abs_dev_m, s.consequence) for s in sums)
        return f"{hits}/{len(sums)} (goal {ATTACK_GOAL_M[track]} m)"

    row("beyond the attack goal", "0", beyond_goal)
    row("stop dev (mean, std)", "all within the lane",
        lambda t, sums: _f(mean_sd(abs_or_none(s.ar_stop_dev_m) for s in sums)))
    row("stopped in lane", "all",
        lambda t, sums: f"{sum(s.consequence == 'stop_in_lane' for s in sums)}/{len(sums)}")

    ld3 = [s for r, s in sim.done if r.tags["setting"] == "ld3"]
    naive = [s for r, s in sim.done if r.tags["setting"] == "ld3-naive-ar"]
    quantities = [("detection dev", _stat(replay["detection_dev"]), mean_sd(s.detection_dev_m for s in ld3)),
                  ("response max dev", _stat(replay["ar_max_dev"]), mean_sd(s.ar_max_dev_m for s in ld3)),
                  ("stop dev", _stat(replay["stop_dev"]), mean_sd(abs_or_none(s.ar_stop_dev_m) for s in ld3))]
    naive_over = sum(s.max_abs_dev_m > ATTACK_GOAL_M["local"] for s in naive)
    lines += ["", f"**Trace replay**: the paper's most aggressive FusionRipper trace injected into the localization "
              f"({replay['title']}); ours: the same trace (`trace:default`) in the simulator-table runs, all "
              "scenarios pooled.", "", "| quantity | paper | ours LD3 |", "|---|---|---|"]
    lines += [f"| {name} (mean, std) | {_f(p)} | {_f(o)} ({len(ld3)} runs) |" for name, p, o in quantities]
    lines.append(f"| NaiveAR beyond the 1.3 m local goal | {replay['naive_over_goal']} | {naive_over} of "
                 f"{len(naive)} runs |")
    paper_vs_ours(out / "trace_replay.png", "Trace replay: LD3 deviations (paper: night-time trace)",
                  [q[0] for q in quantities], [q[1] for q in quantities], [q[2] for q in quantities], "|D| (m)",
                  (paper["lane_straddle_dev"], "paper lane straddle dev"))
    lines += ["", "![trace replay](trace_replay.png)"]
    return "\n".join(lines)


# ---- FusionRipper d × f grid ----------------------------------------------------------------------------
def grid_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    paper, res = values["fusionripper_traces"], results["fusionripper-grid"]
    cells: dict[tuple[str, float, float], list[bool]] = {}
    for run, s in res.done:
        key = (run.tags["track"], run.tags["d"], run.tags["f"])
        cells.setdefault(key, []).append(attack_succeeded(run.tags["track"], s.max_abs_dev_m, s.consequence))
    lines = [_header("FusionRipper d × f grid without defense", paper["label"], [res], out),
             "Success = max |physical D| beyond the attack goal or off the road (the paper's rule).", "",
             "| paper trace | road | paper best d, f | paper success | ours at the paper's d, f | ours best d, f "
             "| ours best success | drives per cell |", "|---|---|---|---|---|---|---|---|"]
    for row in paper["rows"]:
        road = row["road"]
        at = cells.get((road, row["best_d"], row["best_f"]), [])
        mine = {k: v for k, v in cells.items() if k[0] == road}
        best = max(mine, key=lambda k: (np.mean(mine[k]), k[1], k[2]), default=None)
        at_text = f"{100 * np.mean(at):.0f}% ({len(at)})" if at else "–"
        best_text = (f"{best[1]:g}, {best[2]:g} | {100 * np.mean(mine[best]):.0f}%" if best is not None else "– | –")
        drives = sorted({len(v) for v in mine.values()})
        drives_text = "–" if not drives else str(drives[0]) if drives[0] == drives[-1] else f"{drives[0]}–{drives[-1]}"
        lines.append(f"| {row['trace']} | {road} | {row['best_d']:g}, {row['best_f']:g} "
                     f"| {100 * row['success_rate']:.1f}% | {at_text} | {best_text} "
                     f"| {drives_text} |")
    lines += ["", f"![success rate per d × f cell]({_rel(res.folder / 'fusionripper_grid.png', out)})"]
    return "\n".join(lines)


# ---- ROC ------------------------------------------------------------------------------------------------
def roc_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    paper, res = values["roc"], results["roc"]
    ours = roc_table(res.done, res.folder).replace("](roc.png)", f"]({_rel(res.folder / 'roc.png', out)})")
    return "\n".join([_header("Detection ROC: LD3 against SAVIOR", paper["label"], [res], out),
                      f"Paper: LD3 reaches TPR {paper['ld3_tpr']:.0%} at FPR {paper['ld3_fpr']:.0%} on all four "
                      f"traces (b = {paper['b']}, τ = {paper['tau']}); SAVIOR is {paper['savior']}.", "",
                      "Ours:", "", ours])


# ---- stealthy bound -------------------------------------------------------------------------------------
def stealthy_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    paper, res = values["stealthy"], results["stealthy"]
    lines = [_header("Stealthy attack bound", paper["label"], [res], out),
             "Bound = τ + b + F, F the LD fluctuation the attacker catches: 0 (100 %), μ (50 %), μ + 3σ (0.3 %). "
             "Ours: (μ, σ) of |D_LD − D_phys| before the attack, the bound from it, and what the closed-loop "
             "stealthy attacker reached without an alarm (max over the runs; at the margin that reached it).", "",
             "| source | LD fluctuation μ, σ (m) | bound F=0 / μ / μ+3σ (m) | reached without alarm (m) | alarms |",
             "|---|---|---|---|---|"]
    for row in paper["rows"]:
        lines.append(f"| paper {row['trace']} | {_f(_stat(row['fluctuation']))} "
                     f"| {' / '.join(f'{v:.2f}' for v in row['bound'])} | – | – |")
    for det in LD_NOISE_STD:
        for track in STEALTHY_TRACKS:
            cell = [(r, s) for r, s in res.done if r.tags["detector"] == det and r.tags["track"] == track]
            if not cell:
                continue
            stats = fluctuation_stats(res.folder, [r for r, _ in cell])
            bound = " / ".join(f"{v:.2f}" for v in run_bound(*stats, cell[0][0])) if stats else "–"
            reached = max(cell, key=lambda rs: undetected_dev(rs[1]) or 0.0)
            alarms = sum(bool(s.detected) for _, s in cell)
            lines.append(f"| ours {det} {track} | {_f(stats, 3)} | {bound} "
                         f"| {undetected_dev(reached[1]) or 0.0:.2f} (margin {reached[0].tags['margin_sigma']:g} σ) "
                         f"| {alarms}/{len(cell)} |")
    return "\n".join(lines)


# ---- DRP during AR ---------------------------------------------------------------------------------------
def drp_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    paper, res = values["drp"], results["drp-ar"]
    lines = [_header("DRP during the attack response", paper["label"], [res], out),
             f"Paper (DRP deviation trace from 0.7 m, applied during AR): {paper['text']}. Ours: LD3 with the camera "
             "detector; AR deviations over the runs that raised the alarm (a patch that raises none cannot steer "
             "the car).", "",
             "| quantity | paper | " + " | ".join(f"ours {a}" for a in ("drp-trace", "drp-patch")) + " |",
             "|---|---|---|---|"]
    by_attack = {a: _tagged(res.done, attack=a) for a in ("drp-trace", "drp-patch")}
    alarmed = {a: [s for s in sums if s.detected] for a, sums in by_attack.items()}
    stats = {a: (mean_sd(s.ar_max_dev_m for s in al), mean_sd(abs_or_none(s.ar_stop_dev_m) for s in al))
             for a, al in alarmed.items()}
    lines.append("| alarm raised | – | " + " | ".join(f"{len(alarmed[a])}/{len(by_attack[a])}" for a in by_attack)
                 + " |")
    lines.append(f"| response max dev (mean, std) | {_f(_stat(paper['ar_max_dev']))} | "
                 + " | ".join(_f(stats[a][0]) for a in by_attack) + " |")
    lines.append(f"| stop dev (mean, std) | {_f(_stat(paper['stop_dev']))} | "
                 + " | ".join(_f(stats[a][1]) for a in by_attack) + " |")
    lines.append("| runs beyond lane straddle | 0 | " + " | ".join(
        f"{sum(s.max_abs_dev_m > s.lane_straddle_dev_m for s in by_attack[a])}/{len(by_attack[a])}"
        for a in by_attack) + " |")
    lines.append("| max dev over the run (mean, std) | – | " + " | ".join(
        _f(mean_sd(s.max_abs_dev_m for s in by_attack[a])) for a in by_attack) + " |")
    labels = [f"{a} {q}" for a in by_attack for q in ("response max", "stop")]
    paper_vs_ours(out / "drp_ar.png", "DRP during the response", labels,
                  [_stat(paper["ar_max_dev"]), _stat(paper["stop_dev"])] * 2,
                  [stats[a][i] for a in by_attack for i in (0, 1)], "|D| (m)")
    lines += ["", "![DRP during AR](drp_ar.png)"]
    return "\n".join(lines)


# ---- benign false alarms ---------------------------------------------------------------------------------
def residual_max(run_dir: Path) -> float | None:
    """Largest |D_MSF − D_LD| at a fresh lane detection (m): the residual LD3's CUSUM integrates."""
    cols = read_trajectory(run_dir, ("msf_dev", "ld_dev", "ld_fresh"))
    keep = cols["ld_fresh"] == 1
    residual = finite(np.abs(cols["msf_dev"][keep] - cols["ld_dev"][keep]))
    return float(residual.max()) if residual.size else None


def benign_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    paper, benign, sim = values["benign"], results["benign"], results["sim-table"]
    lines = [_header("Benign false alarms", paper["label"], [benign, sim], out),
             f"Paper: {paper['text']}; benign |D_MSF − D_LD| stays below {paper['benign_residual_below']} m. Ours: "
             "LD3 on every benign run of `benign` and `sim-table`.", "",
             "| track | runs | false alarms (paper 0) | max \\|D_MSF − D_LD\\| (m) | max \\|D\\| (m) | consequences |",
             "|---|---|---|---|---|---|"]
    rows: dict[str, list[tuple[Path, RunSummary]]] = {}
    for run, s in benign.done:
        rows.setdefault(run.tags["track"], []).append((benign.folder / run.run_id, s))
    for run, s in sim.done:
        if run.tags["setting"] == "benign":
            rows.setdefault(f"{run.tags['scenario']} (sim-table)", []).append((sim.folder / run.run_id, s))
    for track, items in rows.items():
        sums = [s for _, s in items]
        residual = finite(residual_max(d) for d, _ in items)
        lines.append(f"| {track} | {len(sums)} | {sum(bool(s.detected) for s in sums)} "
                     f"| {residual.max() if residual.size else float('nan'):.2f} "
                     f"| {max(s.max_abs_dev_m for s in sums):.2f} | {consequences(sums)} |")
    return "\n".join(lines)


# ---- ablation -------------------------------------------------------------------------------------------
def ablation_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    res = results["ablation"]
    variants = [v for v in VARIANTS if any(r.tags["variant"] == v for r, _ in res.done)]
    lines = [_header("Ablation of LD3's response (the testbed's own)", "none (the paper mode is its reference)",
                     [res], out),
             "Per attack and response variant: runs in lane, response max |D| and stop |D| (m, mean, std).", "",
             "| attack | variant | in lane | response max dev | stop dev |", "|---|---|---|---|---|"]
    for attack in ABLATION_ATTACKS:
        for variant in variants:
            sums = _tagged(res.done, attack=attack, variant=variant)
            if not sums:
                continue
            label = f"{variant} (default)" if is_default(VARIANTS[variant]) else variant
            in_lane = sum(s.consequence in IN_LANE for s in sums)
            lines.append(f"| {attack} | {label} | {in_lane}/{len(sums)} "
                         f"| {_f(mean_sd(s.ar_max_dev_m for s in sums))} "
                         f"| {_f(mean_sd(abs_or_none(s.ar_stop_dev_m) for s in sums))} |")
    lines += ["", f"![ablation]({_rel(res.folder / 'ablation.png', out)})"]
    return "\n".join(lines)


# ---- adaptive attacks ------------------------------------------------------------------------------------
def adaptive_section(results: dict[str, CampaignResult], values: dict[str, Any], out: Path) -> str:
    res = results.get("adaptive")
    if res is None:
        return "## Security margins against adaptive attackers\n\nNot run in this selection (`ld3 campaign adaptive`)."
    return "\n".join([_header("Security margins against adaptive attackers (the testbed's own)",
                              "none (the paper evaluates attackers that do not know the defense)", [res], out),
                      adaptive_table(res.done, out)])


SECTIONS: tuple[Section, ...] = (sim_section, chassis_section, fr_section, grid_section, roc_section,
                                 stealthy_section, drp_section, benign_section, ablation_section, adaptive_section)


def _commit(summary: RunSummary | dict[str, Any]) -> str | None:
    """The git commit a run's summary (or a search cell's, a dict) records; None when it records none."""
    return summary.git_commit if isinstance(summary, RunSummary) else summary.get("git_commit")


def _sources(done: list[tuple[CampaignRun, Any]]) -> str:
    """The git commits (short; `-dirty`: uncommitted changes) that produced `done`, with their run counts."""
    counts = Counter(_commit(s) or "unknown" for _, s in done)
    return ", ".join(f"{c.split('-')[0][:9]}{'-dirty' if c.endswith('-dirty') else ''}: {n}"
                     for c, n in counts.most_common()) or "–"


def write_paper_report(out: Path, results: dict[str, CampaignResult], *, quick: bool, detector: str) -> Path:
    """`out/report.md` and its figures from the campaigns' finished runs (of the `quick` set or the full one,
    with the camera lane detector `detector`)."""
    values = load_paper_values()
    scale = "quick set: fewer start times, seeds and layouts" if quick else "full set"
    planned = sum(len(r.planned) for r in results.values())
    done = sum(len(r.done) for r in results.values())
    head = [f"# LD3: the paper's results beside ours ({scale})", "",
            f"{done} of {planned} runs done; camera lane detector `{detector}` where the experiment uses "
            f"one. Paper values: `testbed/eval/experiments/paper_values.toml` (each under its label in ld3_paper.tex). "
            f"Regenerate everything: `ld3 paper{' --quick' if quick else ''} --out {out}`.", "",
            "| campaign | runs done | source (git commit: runs) | command |", "|---|---|---|---|"]
    head += [f"| {r.name} | {len(r.done)}/{len(r.planned)} | {_sources(r.done)} | `{r.command}` |"
             for r in results.values()]
    commits = {c for r in results.values() for _, s in r.done if (c := _commit(s)) is not None}
    if len(commits) > 1:  # a summary that records no commit ("unknown" above) is no evidence of another tree
        head += ["", f"**The runs come from {len(commits)} source trees**: a rerun after a code change resumes "
                     "with the new code, so these results mix versions; start from an empty folder to compare one."]
    body = [section(results, values, out) for section in SECTIONS]
    report = out / "report.md"
    report.write_text("\n".join(head) + "\n\n" + "\n\n".join(body) + "\n")
    return report
