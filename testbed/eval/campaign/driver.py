"""Campaigns: many scenario runs, each in its own folder; crash-safe and resumable.

Each run is written into a temporary sibling folder `.<name>.tmp-<pid>` and renamed into place by the
campaign process only once its executor has returned and its `summary.json` reads back as a JSON object, so
a run folder in place is complete and only such a folder counts as done; a rerun skips it. At start, a
leftover temporary folder, or a run folder whose summary.json is missing or unreadable, is removed (the run
is redone) and named on stderr and in `redone.txt`. A run that fails or exceeds its time limit (`timeout`,
default `run_timeout`) is named on stderr and in `failures.txt` (first line `run_id: ErrorType: message`,
the traceback tail indented below it) and the campaign goes on; both files describe the latest invocation.
Warnings a run logs go to its own `run.log`, not the console.

Runs execute on a registered backend (`CAMPAIGN_BACKENDS`: `local`, `ray`, and those installed under the
entry-point group `ld3.campaign_backends`; `testbed.eval.campaign.backend`), which yields each run as it
finishes; this process settles every run the same way, whatever the backend. One campaign process
at a time may use a folder (`.campaign.lock`). The collected summaries go to `runs.csv` (nested fields as
dotted columns) and the campaign's own table to `report.md`; the summaries are read typed (`RunSummary`), and a
run folder whose summary is not one of this version is a one-line error naming its file.
"""

from __future__ import annotations

import csv
import json
import os
import sys
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from tqdm import tqdm

from testbed.errors import UserError
from testbed.eval.campaign.backend import CampaignBackend
from testbed.eval.campaign.local_backend import LocalBackend
from testbed.eval.campaign.ray_backend import RayBackend
from testbed.eval.campaign.run import (
    TMP_MARK,
    CampaignRun,
    RunExecutor,
    RunQueue,
    failure_record,
    remove_path,
    temp_dir,
)
from testbed.eval.run.summary import RunSummary, read_summary
from testbed.registry import Registry

try:
    import fcntl
except ImportError:  # not POSIX: no folder lock
    fcntl = None  # type: ignore[assignment]

LOCK_NAME = ".campaign.lock"

CAMPAIGN_BACKENDS: Registry[CampaignBackend] = Registry("campaign backend", CampaignBackend,
                                                       "ld3.campaign_backends")
"""Where campaign runs execute (`--backend`): built-ins and the installed `ld3.campaign_backends` entry points,
each a `CampaignBackend` instance."""
CAMPAIGN_BACKENDS.add(LocalBackend())
CAMPAIGN_BACKENDS.add(RayBackend())


class CampaignBusyError(RuntimeError):
    """Another campaign process holds the folder's lock."""


def run_and_write(run: CampaignRun, run_dir: Path) -> RunSummary:
    """The default executor: the run's standard outputs into the campaign's temporary run folder."""
    from testbed.eval.run.runner import run_into

    return run_into(run.scenario, run_dir).record


def run_and_write_data(run: CampaignRun, run_dir: Path) -> RunSummary:
    """The executor of runs whose figures are drawn on demand (a search's trials): the standard outputs with
    believed.csv in place of birdseye.png and ar_fusion.png (`ld3 figures` draws them from the folder)."""
    from testbed.eval.run.runner import run_into

    return run_into(run.scenario, run_dir, figures=False).record


def load_summary(run_dir: Path) -> dict[str, Any] | str:
    """The folder's summary.json object, fields unchecked, or why there is none (missing, unreadable or not a JSON
    object): whether a run (or a search cell) in the folder is complete."""
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
    except FileNotFoundError:
        return "summary.json missing"
    except (OSError, ValueError) as exc:
        return f"summary.json unreadable ({type(exc).__name__}: {exc})"
    return summary if isinstance(summary, dict) else "summary.json is not a JSON object"


def typed_summary(run_dir: Path) -> RunSummary | str:
    """The run's typed summary, or why there is none (`load_summary`'s reasons, or a summary not of this version)."""
    if isinstance(problem := load_summary(run_dir), str):
        return problem
    try:
        return read_summary(run_dir / "summary.json")
    except UserError as exc:
        return str(exc)


def settle(run: CampaignRun, out: Path, tmp: Path, error: str | None) -> str | None:
    """Rename a finished run's temporary folder into place, or remove it; returns the failure record if any."""
    if error is None and isinstance(problem := load_summary(tmp), str):
        error = failure_record(run.run_id, "IncompleteRun", f"the executor returned but {problem}")
    if error is None:
        try:
            os.rename(tmp, out / run.run_id)
        except OSError as exc:
            error = failure_record(run.run_id, type(exc).__name__, f"cannot move the run into place: {exc}")
    if error is not None:
        remove_path(tmp)
    return error


@contextmanager
def _folder_lock(out: Path) -> Iterator[None]:
    """Hold `out`'s campaign lock (the OS releases it when this process dies), or raise CampaignBusyError."""
    if fcntl is None:
        yield
        return
    with (out / LOCK_NAME).open("a") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise CampaignBusyError(f"campaign folder {out} is in use by another campaign process") from None
        yield


def check_campaign_dir(out: Path) -> None:
    """A one-line UserError unless `out` is new, empty, or a campaign's folder (it holds the campaign lock):
    a campaign cleans up run folders it finds incomplete, which must never be someone else's files."""
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise UserError(f"--out {out} is a file, not a folder; choose a folder")
    if out.is_dir() and any(out.iterdir()) and not (out / LOCK_NAME).exists():
        raise UserError(f"--out {out} holds files that are not a campaign's; choose a new or empty folder")


def _sweep(run_ids: Sequence[str], out: Path) -> list[str]:
    """Remove the runs' leftover temporary folders and incomplete run folders; `run_id: what` for each."""
    leftovers: dict[Path, list[Path]] = {}
    for parent in {(out / i).parent for i in run_ids}:
        for entry in parent.iterdir() if parent.is_dir() else ():
            if entry.name.startswith(".") and TMP_MARK in entry.name:
                leftovers.setdefault(parent / entry.name[1:entry.name.rindex(TMP_MARK)], []).append(entry)
    redone = []
    for run_id in run_ids:
        final = out / run_id
        for tmp in sorted(leftovers.get(final, [])):
            remove_path(tmp)
            redone.append(f"{run_id}: removed the unfinished temporary folder {tmp.name}")
        if final.exists() and isinstance(problem := load_summary(final), str):
            remove_path(final)
            redone.append(f"{run_id}: removed the incomplete run folder ({problem}); redoing it")
    return redone


def _write_record(path: Path, entries: list[str]) -> None:
    """`entries` into `path`, or no file when there are none (the latest invocation's record)."""
    if entries:
        path.write_text("\n".join(entries) + "\n")
    else:
        path.unlink(missing_ok=True)


def campaign_backend(name: str, address: str | None) -> CampaignBackend:
    """The registered backend `name`, checked to run here with `address` (a backend that takes no address is
    refused one); a one-line UserError otherwise, before anything is written."""
    backend = CAMPAIGN_BACKENDS.get(name)
    if address is not None and not backend.connects:
        connecting = [b.name for b in CAMPAIGN_BACKENDS if b.connects]
        fix = " or ".join(f"--backend {n}" for n in connecting) or "drop --address"
        needs = f"the {connecting[0]} backend" if len(connecting) == 1 else "a backend that connects to one"
        raise UserError(f"a cluster address ({address!r}) needs {needs}: add {fix}")
    backend.check(address)
    return backend


def run_campaign(runs: Sequence[CampaignRun] | RunQueue, out: Path, workers: int | None = None,
                 progress: bool = True, execute: RunExecutor = run_and_write, timeout: float | None = None,
                 backend: str = "local", address: str | None = None) -> list[tuple[CampaignRun, RunSummary]]:
    """Run every campaign run not yet done with `execute`, each within `timeout` seconds (default
    `run_timeout` per run), on the registered `backend` with at most `workers` in flight (its default when
    None) and the cluster `address` where it takes one; returns (run, summary) for all runs that are done. A
    `RunQueue`'s runs are made as the backend draws them (all of them, in order, done or not)."""
    if timeout is not None and not timeout > 0:
        raise UserError(f"timeout must be > 0 s, got {timeout}")
    if workers is not None and workers < 1:
        raise UserError(f"workers must be ≥ 1, got {workers}")
    chosen = campaign_backend(backend, address)
    check_campaign_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    queue = runs if isinstance(runs, RunQueue) else RunQueue([r.run_id for r in runs], {r.run_id: r for r in runs}.get)
    with _folder_lock(out):
        redone = _sweep(queue.run_ids, out)
        for line in redone:
            print(f"{out.name}: {line}", file=sys.stderr)
        _write_record(out / "redone.txt", redone)
        todo = [i for i in queue.run_ids if not (out / i).exists()]
        made: list[CampaignRun] = []
        with tqdm(total=len(todo), desc=out.name, disable=not progress or not todo) as bar:
            drawn = _draw(queue, set(todo), made)
            if todo and not chosen.draws:
                drawn = list(drawn)
            failures = _execute(chosen, drawn, out, execute, timeout, workers, address, bar) if todo else []
        made += [queue.make(i) for i in queue.run_ids[len(made):]]  # nothing to run: made all the same, in order
        _write_record(out / "failures.txt", failures)
        done = done_runs(made, out)
        _write_runs_csv(out / "runs.csv", done)
    return done


def _draw(queue: RunQueue, todo: set[str], made: list[CampaignRun]) -> Iterator[CampaignRun]:
    """The queue's runs to do, each made when drawn; every run made on the way (done ones too, in the queue's
    order) is added to `made`."""
    for run_id in queue.run_ids:
        run = queue.make(run_id)
        made.append(run)
        if run_id in todo:
            yield run


def done_runs(runs: Iterable[CampaignRun], out: Path) -> list[tuple[CampaignRun, RunSummary]]:
    """(run, its typed summary) for each of `runs` complete in `out`; a summary that is not one of this version is a
    one-line UserError naming its file."""
    return [(run, read_summary(out / run.run_id / "summary.json")) for run in runs
            if isinstance(load_summary(out / run.run_id), dict)]


def _execute(backend: CampaignBackend, todo: Iterable[CampaignRun], out: Path, execute: RunExecutor,
             timeout: float | None, workers: int | None, address: str | None, bar: tqdm) -> list[str]:
    """The runs on `backend`, each settled as it finishes; returns the failure records."""
    failures: list[str] = []
    outcomes = backend.run(todo, out, execute, timeout, workers, address)
    try:
        for run, error in outcomes:
            _count_finished(bar, failures, settle(run, out, temp_dir(out, run.run_id), error))
    finally:
        if (close := getattr(outcomes, "close", None)) is not None:  # a generator: stop what is in flight
            close()
    return failures


def _count_finished(bar: tqdm, failures: list[str], error: str | None) -> None:
    """One more run finished: advance the bar; a failure is kept and its first line shown on stderr."""
    bar.update(1)
    if error is not None:
        failures.append(error)
        tqdm.write(error.splitlines()[0], file=sys.stderr)


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


def _write_runs_csv(path: Path, done: Iterable[tuple[CampaignRun, RunSummary]]) -> None:
    rows = [{"run_id": r.run_id, **r.tags, **flatten(s.model_dump(mode="json"))} for r, s in done]
    if not rows:
        return
    keys: list[str] = []
    for row in rows:
        keys += [k for k in row if k not in keys]
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)
