"""One campaign run (or a queue of runs made as they can start) and how any backend attempts it: the run's spec,
its time limit, the temporary folder it is
written into beside its final folder, and a guarded attempt of its executor that returns a failure record
(`run_id: ErrorType: message`, the traceback tail indented below) instead of raising."""

from __future__ import annotations

import logging
import os
import shutil
import signal
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # only named here: a campaign's backends start workers before the simulation's modules load
    from testbed.eval.run.scenario import Scenario
    from testbed.eval.run.summary import RunSummary

TMP_MARK = ".tmp-"
RUN_LOG = "run.log"
SETUP_ALLOWANCE_S = 120.0
SIM_TIME_FACTOR = 10.0
"""Default time limit = SETUP_ALLOWANCE_S + SIM_TIME_FACTOR × simulated duration; the slowest campaign runs
measured (75 neural-detector campaign runs) took 3.3 × their simulated time."""


@dataclass(frozen=True)
class CampaignRun:
    """One run of a campaign: its id (its folder, relative to the campaign's), its scenario and the tags its
    table reads (copied into runs.csv)."""

    run_id: str
    scenario: Scenario
    tags: dict[str, Any]


@dataclass(frozen=True)
class RunQueue:
    """Runs known by their ids before their scenarios: `make(run_id)` gives each run, called once per id in the
    order of `run_ids` as late as the backend allows (a backend that `draws` calls it when a worker is free for
    the run), so that a search asks its sampler for a trial when the trial can start, not for a whole batch
    first."""

    run_ids: Sequence[str]
    make: Callable[[str], CampaignRun]


RunExecutor = Callable[[CampaignRun, Path], "RunSummary"]
"""Runs one campaign run into the folder it is given (a temporary folder, already created) and returns its
summary; it must write summary.json there (the campaign reads that file back, not what is returned). A
module-level function, so that worker processes can import it."""


class RunTimeout(BaseException):
    """A run went past its time limit (a BaseException, so that an executor's `except Exception` cannot
    swallow it)."""


def temp_dir(out: Path, run_id: str) -> Path:
    """The temporary folder this process writes run `run_id` into, beside its final folder."""
    final = out / run_id
    return final.parent / f".{final.name}{TMP_MARK}{os.getpid()}"


def run_timeout(run: CampaignRun) -> float:
    """The default time limit of a run (s): set-up allowance plus a generous multiple of its simulated time."""
    return SETUP_ALLOWANCE_S + SIM_TIME_FACTOR * run.scenario.duration


def failure_record(run_id: str, error: str, message: str, tail: str = "") -> str:
    """`run_id: ErrorType: message` on one line, then `tail` (a traceback tail) indented by four spaces."""
    lines = [f"{run_id}: {error}: {' '.join(message.split())}"]
    lines += [f"    {line}" for line in tail.splitlines() if line.strip()]
    return "\n".join(lines)


def run_limit(run: CampaignRun, timeout: float | None) -> float:
    """The time limit of `run` (s): `timeout`, or its default `run_timeout`."""
    return timeout if timeout is not None else run_timeout(run)


def remove_path(path: Path) -> None:
    """Remove a folder tree, a file or a link; nothing if absent."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


@contextmanager
def _run_log(run_dir: Path) -> Iterator[None]:
    """Send the warnings logged while a run executes to `run_dir`/RUN_LOG (created on the first one) instead of
    the console, where a campaign's runs would interleave them with its progress bar."""
    handler = logging.FileHandler(run_dir / RUN_LOG, delay=True)
    handler.setLevel(logging.WARNING)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    root.addHandler(handler)
    try:
        yield
    finally:
        root.removeHandler(handler)
        handler.close()


def attempt(execute: RunExecutor, run: CampaignRun, tmp: Path) -> str | None:
    """Run the executor into `tmp` (its warnings into RUN_LOG there); None on success, else its failure record
    (no Exception escapes)."""
    try:
        with _run_log(tmp):
            execute(run, tmp)
        return None
    except Exception as exc:  # a failing run is reported, never allowed to sink the campaign
        frames = traceback.StackSummary.from_list(traceback.extract_tb(exc.__traceback__)[-3:]).format()
        return failure_record(run.run_id, type(exc).__name__, str(exc), "".join(frames))


@contextmanager
def _alarm(seconds: float) -> Iterator[None]:
    """Raise RunTimeout in the main thread after `seconds` (SIGALRM). In-process so that a script without a
    `__main__` guard, a debugger or a notebook work as they are; the alarm interrupts Python code and blocking
    system calls, not one long C call. An outer alarm (pytest-timeout's) is re-armed afterwards, deferred by
    at most `seconds`. Off the main thread no signal can be used: there the run has no limit."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"):
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise RunTimeout(f"over its {seconds:g} s limit")

    previous = signal.signal(signal.SIGALRM, expire)
    t0 = time.monotonic()
    outer_delay, outer_interval = signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        try:
            signal.setitimer(signal.ITIMER_REAL, 0)
        finally:
            signal.signal(signal.SIGALRM, previous)
            if outer_delay > 0:
                signal.setitimer(signal.ITIMER_REAL, max(outer_delay - (time.monotonic() - t0), 1e-3),
                                 outer_interval)


def attempt_within(execute: RunExecutor, run: CampaignRun, tmp: Path, limit_s: float) -> str | None:
    """`attempt` in this process under `_alarm(limit_s)`; a run over the limit is a RunTimeout record."""
    try:
        with _alarm(limit_s):
            return attempt(execute, run, tmp)
    except RunTimeout as exc:
        return failure_record(run.run_id, "RunTimeout", str(exc))


