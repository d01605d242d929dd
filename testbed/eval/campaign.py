"""Campaigns: many scenario runs in worker processes, each in its own folder, resumable.

A run whose `summary.json` exists is not run again, so a campaign interrupted half-way continues
where it stopped; a run that fails is recorded in `failures.txt` with its error and the campaign goes on.
The collected summaries go to `runs.csv` (nested fields as dotted columns) and the campaign's own table to
`report.md`.
"""

from __future__ import annotations

import csv
import json
import multiprocessing as mp
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from testbed.eval.scenario import Scenario


@dataclass(frozen=True)
class CampaignRun:
    run_id: str
    scenario: Scenario
    tags: dict[str, Any]


RunExecutor = Callable[[CampaignRun, Path], dict[str, Any]]
"""Runs one campaign run into its folder and returns its summary; summary.json must be its last output
(its presence marks the run done). A module-level function, so that worker processes can import it."""


def run_and_write(run: CampaignRun, run_dir: Path) -> dict[str, Any]:
    """The default executor: `run_scenario` with the standard outputs."""
    from testbed.eval.runner import run_scenario

    return run_scenario(run.scenario, run_dir).summary


def _execute(job: tuple[CampaignRun, Path, RunExecutor]) -> tuple[str, dict[str, Any] | None, str | None]:
    run, out, execute = job
    try:
        return run.run_id, execute(run, out / run.run_id), None
    except Exception as exc:  # a failing run is reported, never allowed to sink the campaign
        return run.run_id, None, f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=3)}"


def run_campaign(runs: Sequence[CampaignRun], out: Path, workers: int = 2, progress: bool = True,
                 execute: RunExecutor = run_and_write) -> list[tuple[CampaignRun, dict[str, Any]]]:
    """Run every campaign run not yet done with `execute`; returns (run, summary) for all runs that have a
    summary."""
    out.mkdir(parents=True, exist_ok=True)
    by_id = {r.run_id: r for r in runs}
    todo = [(r, out, execute) for r in runs if not (out / r.run_id / "summary.json").exists()]
    failures: list[str] = []
    if todo:
        ctx = mp.get_context("spawn")
        with ctx.Pool(processes=max(1, workers)) as pool:
            it = pool.imap_unordered(_execute, todo)
            for run_id, _summary, error in tqdm(it, total=len(todo), desc=out.name, disable=not progress):
                if error is not None:
                    failures.append(f"{run_id}: {error}")
            pool.close()  # let the workers exit on their own: terminating them leaks their semaphores
            pool.join()
    if failures:
        (out / "failures.txt").write_text("\n".join(failures))
    done = []
    for run_id, run in by_id.items():
        path = out / run_id / "summary.json"
        if path.exists():
            done.append((run, json.loads(path.read_text())))
    _write_runs_csv(out / "runs.csv", done)
    return done


def flatten(value: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested dicts as dotted keys (`attack.kind`, `defense_params.b`); lists as JSON text."""
    flat: dict[str, Any] = {}
    for key, item in value.items():
        name = f"{prefix}{key}"
        if isinstance(item, dict):
            flat.update(flatten(item, f"{name}."))
        elif isinstance(item, list):
            flat[name] = json.dumps(item)
        else:
            flat[name] = item
    return flat


def _write_runs_csv(path: Path, done: Iterable[tuple[CampaignRun, dict[str, Any]]]) -> None:
    rows = [{"run_id": r.run_id, **r.tags, **flatten(s)} for r, s in done]
    if not rows:
        return
    keys: list[str] = []
    for row in rows:
        keys += [k for k in row if k not in keys]
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)

