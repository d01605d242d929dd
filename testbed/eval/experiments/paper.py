"""`ld3 paper`: every experiment of the paper in one command, resumable, and one report with the paper's
values beside ours.

Each experiment is a registered campaign run into `OUT/<campaign>` by `run_named` (so a rerun skips the runs
already in place and every campaign folder also has its own report.md); `--quick` keeps, per campaign, the
runs matching its quick globs (fewer start times, seeds and layouts) and still fills every table. The report
(`OUT/report.md`, figures beside it) is written by testbed.eval.experiments.paper_report from the finished runs.
"""

from __future__ import annotations

import shlex
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from testbed.errors import UserError
from testbed.eval.campaign.driver import CampaignRun, done_runs, load_summary
from testbed.eval.experiments.campaigns import CAMPAIGNS, run_named, selected_runs
from testbed.eval.experiments.paper_report import CampaignResult, write_paper_report
from testbed.eval.run.scenario import ScenarioError, check_needs
from testbed.eval.run.summary import RunSummary


@dataclass(frozen=True)
class Experiment:
    """A campaign the paper report reads, and the comma-separated run-id globs of its quick set."""

    campaign: str
    quick: str


EXPERIMENTS = (
    Experiment("sim-table", "*-start10,*/benign-seed0"),
    Experiment("chassis", "*-rep0"),
    Experiment("fusionripper-ld3", "*@101-seed1-start12.5,*@101-seed1-start21.5"),
    Experiment("fusionripper-grid", "*-drive0"),
    Experiment("roc", "local-benign-seed0,local-benign-seed1,local-fit-seed100,local-fr-*-start13"),
    Experiment("stealthy", "oracle/*-seed1,classical/local-*-seed1,neural/local-*-seed1"),
    Experiment("drp-ar", "drp-trace/*-start10-seed1,drp-patch/*-at62-seed1"),
    Experiment("benign", "highway-seed0,local-seed0,parking-lot-seed0"),
    Experiment("ablation", "paper/*-seed1-start12,heading-fused-clamp0.02-window5/*-seed1-start12"),
    Experiment("adaptive", "local/ld3-paper/msf-output,local/ld3/msf-output"),
)

WALL_PER_SIM_S = {"neural": 0.5, "classical": 0.5, "oracle": 0.05, "none": 0.05}
"""Seconds of one core per simulated second of a run, by lane detector (the camera is rendered for neural and
classical only; classical taken as neural), measured on the 2-core development machine (docs/decisions.md).
Runs that stop early take less: the estimate is an upper bound."""
SETUP_S = 2.0
CAN_SLOWDOWN = 3.0
"""The lockstep CAN link (bridge, ECU emulator, frame log) against a direct oracle run."""
CAN_CAMPAIGNS = frozenset({"chassis"})


@dataclass(frozen=True)
class PaperOptions:
    out: Path
    quick: bool = False
    workers: int = 2
    detector: str = "neural"
    timeout: float | None = None
    progress: bool = False
    backend: str = "local"
    address: str | None = None


def check_registered() -> None:
    """Refuse to start when a campaign of `EXPERIMENTS` is not registered, naming where it comes from."""
    missing = [e.campaign for e in EXPERIMENTS if e.campaign not in CAMPAIGNS]
    if missing:
        raise ValueError(f"campaign(s) {', '.join(missing)} not registered: they come from installed packages' "
                         "ld3.campaigns entry points (chassis: the hil package); reinstall with `pip install -e .`")


def selection(exp: Experiment, quick: bool) -> str | None:
    return exp.quick if quick else None


def planned_runs(options: PaperOptions) -> dict[str, list[CampaignRun]]:
    """Every experiment's runs for these options, by campaign name; ScenarioError, naming the fix, when a run's
    attack or defense could not act with its detector (e.g. a painted patch with `--detector oracle`)."""
    check_registered()
    plan = {e.campaign: selected_runs(e.campaign, options.detector, selection(e, options.quick)) for e in EXPERIMENTS}
    for name, runs in plan.items():
        for run in runs:
            try:
                check_needs(run.scenario)
            except ScenarioError as exc:
                raise ScenarioError(f"{name} run {run.run_id}: {exc}") from None
    return plan


def campaign_command(exp: Experiment, options: PaperOptions) -> str:
    """The `ld3 campaign` command that regenerates (or resumes) one experiment's runs and its own report."""
    parts = ["ld3", "campaign", exp.campaign, "--out", str(options.out / exp.campaign), "--detector", options.detector]
    if (select := selection(exp, options.quick)) is not None:
        parts += ["--runs", select]
    return shlex.join(parts)


def is_done(run: CampaignRun, folder: Path) -> bool:
    return isinstance(load_summary(folder / run.run_id), dict)


def estimate_s(campaign: str, runs: list[CampaignRun]) -> float:
    """Upper-bound one-core wall seconds for `runs` of `campaign` (`WALL_PER_SIM_S`, `SETUP_S`)."""
    slowdown = CAN_SLOWDOWN if campaign in CAN_CAMPAIGNS else 1.0
    return sum((SETUP_S + slowdown * WALL_PER_SIM_S.get(r.scenario.detector, 0.5) * r.scenario.duration)
               * r.tags.get("trials", 1) for r in runs)


def announce_plan(plan: dict[str, list[CampaignRun]], options: PaperOptions) -> str:
    """What is about to run: per campaign the runs to do (of the planned), and the total estimated time."""
    lines, total_runs, total_s = [], 0, 0.0
    for name, runs in plan.items():
        todo = [r for r in runs if not is_done(r, options.out / name)]
        seconds = estimate_s(name, todo)
        total_runs, total_s = total_runs + len(todo), total_s + seconds
        lines.append(f"  {name:18s} {len(todo):5d} of {len(runs):5d} runs to do, ≤ {seconds / 60:6.1f} core-min")
    workers = max(1, options.workers)
    scale = "quick" if options.quick else "full"
    wall_min = total_s / 60 / workers
    duration = f"{wall_min:.0f} min" if wall_min < 90 else f"{wall_min / 60:.1f} h"
    lines.insert(0, f"ld3 paper ({scale}): {total_runs} runs to do, estimated ≤ {duration} with {workers} worker(s) "
                    "(an upper bound on an unloaded machine: most attacked runs stop early)")
    return "\n".join(lines)


def run_experiment(exp: Experiment, options: PaperOptions) -> CampaignResult:
    """Run (or resume) one experiment's campaign into `OUT/<campaign>` through `run_named`, then collect it."""
    folder = options.out / exp.campaign
    select = selection(exp, options.quick)
    run_named(exp.campaign, folder, detector=options.detector, workers=options.workers, progress=options.progress,
              select=select, timeout=options.timeout, backend=options.backend, address=options.address)
    planned = selected_runs(exp.campaign, options.detector, select)
    if CAMPAIGNS.get(exp.campaign).searches is None:
        done: list[tuple[CampaignRun, RunSummary | dict[str, Any]]] = [*done_runs(planned, folder)]
    else:  # a campaign of searches: each cell's own summary (`testbed.eval.experiments.adaptive`)
        done = [(run, cell) for run in planned if isinstance(cell := load_summary(folder / run.run_id), dict)]
    return CampaignResult(exp.campaign, folder, campaign_command(exp, options), planned, done)


PAPER_FILES = ("report.md",)
PAPER_FIGURE_SUFFIXES = (".png", ".svg", ".pdf")


def check_paper_out(out: Path) -> None:
    """A UserError when `out` holds anything a paper run did not write (a campaign's runs.csv, a folder other than
    an experiment's campaign, a file other than the report and its figures): resuming never writes into it."""
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} is a file, not a folder; choose a folder")
    campaigns = {exp.campaign for exp in EXPERIMENTS}
    for entry in sorted(out.iterdir()) if out.is_dir() else ():
        ours = (entry.name in campaigns and entry.is_dir()) or (entry.is_file() and (
            entry.name in PAPER_FILES or entry.suffix in PAPER_FIGURE_SUFFIXES))
        if not ours:
            raise UserError(f"--out {out} holds {entry.name}, which a paper run does not write: choose a new or empty "
                            f"folder, or the folder of an earlier `ld3 paper`")


def run_paper(options: PaperOptions, announce: Callable[[str], None] = print) -> Path:
    """Run every experiment (resuming) and write `OUT/report.md` with its figures; returns the report path."""
    check_paper_out(options.out)
    plan = planned_runs(options)
    announce(announce_plan(plan, options))
    results = {}
    for exp in EXPERIMENTS:
        announce(f"ld3 paper: {exp.campaign} ({len(plan[exp.campaign])} runs) -> {options.out / exp.campaign}")
        results[exp.campaign] = run_experiment(exp, options)
    return write_paper_report(options.out, results, quick=options.quick, detector=options.detector)
